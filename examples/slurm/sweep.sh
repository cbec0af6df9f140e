#!/usr/bin/env bash
# An ablation table as independent tasks: scenes × presets × seeds, each task simulate → train → eval into
# $OUT/<scene>/<preset>/seed<seed>/ (metrics.json last). Under Slurm, a job array runs one task per array
# index (sweep.sbatch); without Slurm, `sweep.sh` runs every task in a plain loop, and `sweep.sh K` runs task
# K. Every task can be rerun after a crash, a preemption or a time limit: a finished task (metrics.json
# present) is skipped, a training run continues from its checkpoint (train --resume), and the simulated
# recordings are written once, atomically (to a temporary folder, then renamed).
#
# Settings (environment): EVNERF (the binary; default build/examples/evnerf), OUT (default sweep_out),
# SCENES (built-in scenes, 'random' is not one; default "planes object room"), PRESETS (default "fast
# fast-slice"), SEEDS (default "1 2 3"), ITERS (default 6000), THREADS (default: Slurm's CPUs per task,
# else all), WIDTH and HEIGHT (the simulated sensor; default 240×180).
# Then: python3 examples/slurm/gather.py $OUT  (one table of every metrics.json).
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
EVNERF=${EVNERF:-$HERE/../../build/examples/evnerf}
OUT=${OUT:-sweep_out}
read -r -a scenes <<<"${SCENES:-planes object room}"
read -r -a presets <<<"${PRESETS:-fast fast-slice}"
read -r -a seeds <<<"${SEEDS:-1 2 3}"
ITERS=${ITERS:-6000}
THREADS=${THREADS:-${SLURM_CPUS_PER_TASK:-0}}
WIDTH=${WIDTH:-240}
HEIGHT=${HEIGHT:-180}
n_tasks=$((${#scenes[@]} * ${#presets[@]} * ${#seeds[@]}))
[ -x "$EVNERF" ] || { echo "sweep: no evnerf binary at $EVNERF (set EVNERF)" >&2; exit 1; }

# Task k → (scene, preset, seed), seeds fastest.
run_task() {
  local k=$1
  if ! [[ "$k" =~ ^[0-9]+$ ]] || ((k >= n_tasks)); then
    echo "sweep: task '$k' is not one of 0..$((n_tasks - 1))" >&2
    return 2
  fi
  local seed=${seeds[$((k % ${#seeds[@]}))]}
  local preset=${presets[$((k / ${#seeds[@]} % ${#presets[@]}))]}
  local scene=${scenes[$((k / (${#seeds[@]} * ${#presets[@]})))]}
  local rec="$OUT/recordings/${scene}_${WIDTH}x${HEIGHT}" dir="$OUT/$scene/$preset/seed$seed"
  if [ -f "$dir/metrics.json" ]; then
    echo "task $k ($scene, $preset, seed $seed): done before, skipped"
    return 0
  fi
  echo "task $k ($scene, $preset, seed $seed)"
  if [ ! -d "$rec" ]; then  # two tasks may simulate the same scene at once: each in its own folder, one rename wins
    local tmp="$rec.tmp.$$.${SLURM_ARRAY_TASK_ID:-0}"
    "$EVNERF" simulate "$scene" --out "$tmp" --width "$WIDTH" --height "$HEIGHT" >/dev/null
    mv -T "$tmp" "$rec" 2>/dev/null || rm -rf "$tmp"
  fi
  "$EVNERF" train "$rec" --preset "$preset" --seed "$seed" --iterations "$ITERS" --threads "$THREADS" --out "$dir" --resume --quiet
  "$EVNERF" eval "$dir/model.ckpt" "$rec" --out "$dir/eval" >"$dir/eval.txt"
  cp "$dir/eval/metrics.json" "$dir/metrics.json.tmp" && mv "$dir/metrics.json.tmp" "$dir/metrics.json"
}

mkdir -p "$OUT/recordings"
if [ $# -ge 1 ]; then
  run_task "$1"
elif [ -n "${SLURM_ARRAY_TASK_ID:-}" ]; then
  run_task "$SLURM_ARRAY_TASK_ID"
else
  echo "sweep: $n_tasks tasks (${#scenes[@]} scenes × ${#presets[@]} presets × ${#seeds[@]} seeds), one after another"
  for ((k = 0; k < n_tasks; ++k)); do run_task "$k"; done
fi
