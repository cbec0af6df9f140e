#!/usr/bin/env bash
# The network ratios under a noisy machine: each of our MLP benchmarks runs right next to the PyTorch
# peer's same network (best configuration), pair after pair, the order flipping every pair; each pair
# gives a ratio, and the script prints their median and range, written to bench/results/speed_ISA.csv
# (RESULTS) and docs/results.md. Usage: bench/pairs.sh [pairs]
# ISA=avx2: both sides on their AVX2 + FMA paths on a CPU with AVX-512 (ours built with EVNERF_NO_AVX512 in
# build-bench-avx2, the peer with OpenBLAS's AVX2 kernels).
set -euo pipefail
cd "$(dirname "$0")/.."
PAIRS=${1:-10}
PEER=../shared/peers/peer_torch.py
if [ ! -f "$PEER" ]; then
  echo "bench/pairs.sh: needs the peer $PEER (see ../shared/peers/README.md)" >&2
  exit 1
fi
scripts/deps.sh libbenchmark-dev python3-torch python3-numpy libopenblas0-openmp libtcmalloc-minimal4
. bench/isa.sh  # B: the build for ISA
OUT=$B/pairs; rm -rf "$OUT"; mkdir -p "$OUT"
. bench/peer_config.sh  # BEST: the peer's flags for this CPU
ours() {  # width, pair
  OMP_NUM_THREADS=2 "$B"/bench/evnerf_bench --benchmark_filter="BM_fma_peak|BM_mlp_fused<$1>/" \
    --benchmark_format=json --benchmark_out="$OUT/ours_$1_$2.json" --benchmark_out_format=json >/dev/null
}
peer() {  # width, samples, pair
  /usr/bin/python3 "$PEER" --mode mlp --width "$1" --n-samples "$2" $BEST > "$OUT/peer_$1_$3.json"
}
for p in $(seq "$PAIRS"); do
  if [ $((p % 2)) = 1 ]; then
    ours 256 "$p"; peer 256 16384 "$p"; ours 64 "$p"; peer 64 65536 "$p"
  else
    peer 256 16384 "$p"; ours 256 "$p"; peer 64 65536 "$p"; ours 64 "$p"
  fi
done
python3 bench/pairs.py "$OUT" "$PAIRS" "${ISA:-native}" "$CPU_FEATURES" "$OPENBLAS_CORE"
# The current figures are kept in the repository (RESULTS, default bench/results; empty: not copied), one
# file per ISA; bench/results.py puts them in docs/results.md.
RESULTS=${RESULTS-bench/results}
if [ -n "$RESULTS" ]; then
  mkdir -p "$RESULTS" && cp "$OUT/pairs.csv" "$RESULTS/speed_${ISA:-native}.csv" && echo "copied to $RESULTS/speed_${ISA:-native}.csv"
  python3 bench/results.py
fi
