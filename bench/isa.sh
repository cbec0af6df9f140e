# Sourced by bench/pairs.sh and bench/formats.sh: the build for ISA (native, or avx2: the AVX2 + FMA path on
# a CPU with AVX-512, built with EVNERF_NO_AVX512), configured and built in B (build-bench or build-bench-avx2)
# with the benchmarks; TARGET (optional) narrows the build to one executable.
case "${ISA:-native}" in
  native) B=build-bench; NO512=OFF ;;
  avx2) B=build-bench-avx2; NO512=ON ;;
  *) echo "$(basename "$0"): ISA is native or avx2, not '$ISA'" >&2; exit 2 ;;
esac
cmake -S . -B "$B" -G Ninja -DCMAKE_BUILD_TYPE=Release -DEVNERF_BUILD_BENCH=ON -DEVNERF_BUILD_TESTS=OFF \
  -DEVNERF_BUILD_EXAMPLES=OFF -DEVNERF_NO_AVX512="$NO512" >/dev/null
cmake --build "$B" ${TARGET:+--target "$TARGET"} -j"$(nproc)" >/dev/null
