# Sourced by bench/run.sh and bench/pairs.sh: the PyTorch peer's best configuration for the CPU this runs on
# (../shared/peers/README.md), with the OpenBLAS kernels chosen from the CPU's vector features: SkylakeX
# only where AVX-512 (F, BW, VL) is there, Zen or Haswell (by vendor) with AVX2 + FMA, Sandybridge with AVX
# alone. Sets OPENBLAS_CORE, BEST (the peer's flags) and CPU_FEATURES and says which it chose; exits with a reason on a
# CPU without AVX, where neither side's fast kernels run. ISA=avx2 measures the AVX2 + FMA paths on a CPU
# with AVX-512: the peer then takes the AVX2 kernels too.
. bench/cpu.sh  # has, CPU_FEATURES (the CPU's own, named in the results)
cpu_vendor=$(grep -m1 '^vendor_id' /proc/cpuinfo | awk '{print $3}')
if [ "${ISA:-}" = avx2 ]; then
  cpu_flags=${cpu_flags// avx512f / }
fi
if has avx512f && has avx512bw && has avx512vl; then
  OPENBLAS_CORE=SkylakeX
elif has avx2 && has fma; then
  if [ "$cpu_vendor" = AuthenticAMD ]; then OPENBLAS_CORE=Zen; else OPENBLAS_CORE=Haswell; fi
elif has avx; then
  OPENBLAS_CORE=Sandybridge
else
  echo "$(basename "$0"): this CPU has no AVX; the benchmarks compare AVX kernels and are not run here" >&2
  exit 3
fi
BEST="--openblas-core $OPENBLAS_CORE --blas-variant openmp --omp-wait passive --malloc tcmalloc --threads 2"
echo "peer: OpenBLAS kernels $OPENBLAS_CORE for this CPU ($CPU_FEATURES)${ISA:+ as ISA=$ISA}" >&2
