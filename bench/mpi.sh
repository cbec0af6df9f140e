#!/usr/bin/env bash
# Data-parallel training on this machine, and a model of N nodes (bench/README.md, "MPI").
# For Fast and Paper, pair after pair (the order flipping every pair), the same two-shard step is run as
#   A: one process, 2 threads, --shards 2           (the reference, in the same run)
#   B: mpirun -np 2, 1 thread each, exchange auto    (sparse where fewer bytes)
#   C: mpirun -np 2, 1 thread each, exchange dense
# and bench/mpi.py prints the ratios of their step times (medians of the pair ratios), the bytes and seconds
# of the exchange per step, and the N-node model from these figures.
# Usage: bench/mpi.sh [pairs] [fast steps] [paper steps]
set -euo pipefail
cd "$(dirname "$0")/.."
PAIRS=${1:-3}
FAST_STEPS=${2:-150}
PAPER_STEPS=${3:-2}
scripts/deps.sh libopenmpi-dev openmpi-bin
cmake -S . -B build-mpi -G Ninja -DCMAKE_BUILD_TYPE=Release -DEVNERF_MPI=ON -DEVNERF_BUILD_TESTS=OFF -DEVNERF_PYTHON=OFF >/dev/null
cmake --build build-mpi -j"$(nproc)" --target evnerf_cli >/dev/null
EV=build-mpi/examples/evnerf
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl_vader_single_copy_mechanism=none
OUT=build-mpi/bench; rm -rf "$OUT"; mkdir -p "$OUT"
"$EV" simulate planes --out "$OUT/rec" >/dev/null 2>&1
run() {  # kind preset steps pair
  local dir="$OUT/$1_$2_$4" common=(train "$OUT/rec" --preset "$2" --iterations "$3" --seed 1 --quiet --checkpoint-every 0)
  case $1 in
    A) "$EV" "${common[@]}" --out "$dir" --shards 2 --threads 2 ;;
    B) mpirun --oversubscribe --bind-to none -np 2 "$EV" "${common[@]}" --out "$dir" --threads 1 --exchange auto ;;
    C) mpirun --oversubscribe --bind-to none -np 2 "$EV" "${common[@]}" --out "$dir" --threads 1 --exchange dense ;;
  esac >/dev/null 2>&1
}
for preset in fast paper; do
  steps=$FAST_STEPS; [ $preset = paper ] && steps=$PAPER_STEPS
  for p in $(seq "$PAIRS"); do
    if [ $((p % 2)) = 1 ]; then order="A B C"; else order="C B A"; fi
    for k in $order; do run $k $preset "$steps" "$p"; done
  done
done
python3 bench/mpi.py "$OUT" "$PAIRS"
