#!/usr/bin/env bash
# Builds bench/, runs it and the PyTorch peer (best configuration, see ../shared/peers/README.md) in the
# same run, alternating, and prints the ratios from medians. Usage: bench/run.sh [repetitions]
set -euo pipefail
cd "$(dirname "$0")/.."
REPS=${1:-3}
# The PyTorch peer and its best configuration's libraries (../shared/peers/README.md).
scripts/deps.sh libbenchmark-dev python3-torch python3-numpy libopenblas0-openmp libtcmalloc-minimal4
cmake -S . -B build-bench -G Ninja -DCMAKE_BUILD_TYPE=Release -DEVNERF_BUILD_BENCH=ON -DEVNERF_BUILD_TESTS=OFF \
  -DEVNERF_BUILD_EXAMPLES=OFF >/dev/null
cmake --build build-bench -j"$(nproc)" >/dev/null
OUT=build-bench/results; mkdir -p "$OUT"; rm -f "$OUT"/ours_*.json; : > "$OUT/peer.jsonl"; : > "$OUT/peer_bf16.jsonl"  # no stale runs
. bench/peer_config.sh  # BEST and OPENBLAS_CORE: the peer's configuration for this CPU
LIB=/usr/lib/x86_64-linux-gnu
# What the best-configuration flags set, in advance, so the autocast wrapper's peer does not re-execute.
AUTOCAST_ENV=(env LD_LIBRARY_PATH="$LIB/openblas-openmp:${LD_LIBRARY_PATH:-}" LD_PRELOAD="$LIB/libtcmalloc_minimal.so.4"
  OPENBLAS_CORETYPE="$OPENBLAS_CORE" OMP_WAIT_POLICY=PASSIVE OMP_NUM_THREADS=2 OPENBLAS_NUM_THREADS=2)
PEER=../shared/peers/peer_torch.py
for r in $(seq "$REPS"); do
  OMP_NUM_THREADS=2 build-bench/bench/evnerf_bench --benchmark_format=json --benchmark_out="$OUT/ours_$r.json" \
    --benchmark_out_format=json >/dev/null
  if [ -f "$PEER" ] && /usr/bin/python3 -c "import torch" 2>/dev/null; then
    /usr/bin/python3 "$PEER" --mode mlp --width 256 --n-samples 16384 $BEST >> "$OUT/peer.jsonl"
    /usr/bin/python3 "$PEER" --mode mlp --width 64 --n-samples 65536 $BEST >> "$OUT/peer.jsonl"
    /usr/bin/python3 "$PEER" --mode step --width 64 --n-coarse 32 --n-fine 32 --batch-rays 1024 --chunk-rays 256 --iterations 3 $BEST >> "$OUT/peer.jsonl"
    /usr/bin/python3 "$PEER" --mode step --width 256 --n-coarse 64 --n-fine 128 --batch-rays 1024 --chunk-rays 32 --iterations 2 --warmup 1 $BEST >> "$OUT/peer.jsonl"
    # The same peer under PyTorch's bf16 autocast: the like-for-like reference for our Bf16 networks.
    AC=("${AUTOCAST_ENV[@]}" /usr/bin/python3 bench/peer_autocast.py "$PEER")
    "${AC[@]}" --mode mlp --width 256 --n-samples 16384 $BEST >> "$OUT/peer_bf16.jsonl"
    "${AC[@]}" --mode mlp --width 64 --n-samples 65536 $BEST >> "$OUT/peer_bf16.jsonl"
    "${AC[@]}" --mode step --width 64 --n-coarse 32 --n-fine 32 --batch-rays 1024 --chunk-rays 256 --iterations 3 $BEST >> "$OUT/peer_bf16.jsonl"
    "${AC[@]}" --mode step --width 256 --n-coarse 64 --n-fine 128 --batch-rays 1024 --chunk-rays 32 --iterations 2 --warmup 1 $BEST >> "$OUT/peer_bf16.jsonl"
  fi
done
python3 bench/ratios.py "$OUT"
