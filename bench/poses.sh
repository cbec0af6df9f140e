#!/usr/bin/env bash
# Poses only roughly known: each scene simulated at each pose-noise level (`simulate --pose-noise T,R
# --time-offset 0.01`; level 0 is the clean recording), trained with the default preset and steps with and
# without pose refinement (`train --refine-poses --learn-time-offset`), and scored by eval against the
# recording's frames (global-log-affine) with the pose error at the slice boundaries against the true poses
# (groundtruth_true.txt). The scene `slider` is the real IJRR chunk (../shared/data/ijrr_slider_depth_chunk,
# skipped when absent) on its own motion-capture poses, at no added noise and without true poses to score
# them against. Writes $OUT/poses.csv, copies it to bench/results/ (RESULTS; empty: not copied) and
# regenerates docs/results.md. About 4 minutes a run on 2 cores (refinement adds its share).
# Usage: bench/poses.sh [SCENE ...]   (default: planes room object slider)
# Environment: LEVELS (noise levels as T,R pairs: "0,0 0.01,0.5 0.02,1 0.05,2"), OFFSET (seconds, 0.01),
#              SEEDS ("1 2": each is the simulation's and the training's seed), THREADS (2), OUT (out/poses),
#              BUILD (build), EVNERF (the binary: $BUILD/examples/evnerf), KEEP=1 (reuse runs whose
#              evaluation exists), REFINE_FLAGS (the refinement's train flags).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-out/poses}
LEVELS=${LEVELS:-"0,0 0.01,0.5 0.02,1 0.05,2"}
OFFSET=${OFFSET:-0.01}
SEEDS=${SEEDS:-"1 2"}
THREADS=${THREADS:-2}
REFINE_FLAGS=${REFINE_FLAGS:-"--refine-poses --learn-time-offset"}
RESULTS=${RESULTS-bench/results}
. bench/evnerf_bin.sh  # EV
SCENES=("$@")
[ ${#SCENES[@]} -gt 0 ] || SCENES=(planes room object slider)
SLIDER=../shared/data/ijrr_slider_depth_chunk
mkdir -p "$OUT"
CSV="$OUT/poses.csv"
echo "scene,seed,noise_translation,noise_rotation_deg,offset_s,refine,psnr,ssim,error_translation,error_rotation_deg,given_translation,given_rotation_deg,learned_offset_s,train_seconds,threads" > "$CSV"
for scene in "${SCENES[@]}"; do
  levels=$LEVELS
  if [ "$scene" = slider ]; then
    [ -d "$SLIDER" ] || { echo "poses: $SLIDER is absent; slider skipped" >&2; continue; }
    levels="0,0"
  fi
  for seed in $SEEDS; do
    for level in $levels; do
      IFS=',' read -r nt nr <<<"$level"
      off=$OFFSET
      if [ "$nt" = 0 ] && [ "$nr" = 0 ]; then off=0; fi
      rec="$OUT/$scene-$seed-$nt-$nr-$off/recording"
      scene_flags=()
      if [ "$scene" = slider ]; then
        rec=$SLIDER
        scene_flags=(--near 0.1 --far 5)
      else
        [ -f "$rec/events.txt" ] || "$EV" simulate "$scene" --seed "$seed" --pose-noise "$nt,$nr" --time-offset "$off" --out "$rec" > /dev/null
      fi
      for refine in 0 1; do
        dir="$OUT/$scene-$seed-$nt-$nr-$off/refine$refine"
        flags=("${scene_flags[@]}")
        if [ "$refine" = 1 ]; then
          read -r -a more <<<"$REFINE_FLAGS"
          flags+=("${more[@]}")
        fi
        if [ "${KEEP:-0}" != 1 ] || [ ! -f "$dir/eval/metrics.json" ]; then
          rm -rf "$dir"
          mkdir -p "$dir"
          "$EV" train "$rec" --out "$dir/run" --seed "$seed" --threads "$THREADS" --quiet "${flags[@]}" > "$dir/train.txt" 2>&1
          "$EV" eval "$dir/run/model.ckpt" "$rec" --out "$dir/eval" > "$dir/eval.txt" 2>&1
        fi
        python3 - "$dir" "$scene" "$seed" "$nt" "$nr" "$off" "$refine" "$THREADS" >> "$CSV" <<'PY'
import json, re, sys
d, scene, seed, nt, nr, off, refine, threads = sys.argv[1:]
m = json.load(open(f"{d}/eval/metrics.json"))
assert m["alignment"] == "global-log-affine", m["alignment"]
ours = next(v for k, v in m["methods"].items() if k.startswith("evnerf"))
p = m.get("poses", {})
err = p.get("error_refined") or p.get("error_given") or {}
given = p.get("error_given") or {}
secs = sum(float(x) for x in re.findall(r" steps in ([0-9.]+) s", open(f"{d}/train.txt").read()))
print(",".join(str(x) for x in [scene, seed, nt, nr, off, refine, f"{ours['psnr']:.2f}", f"{ours['ssim']:.4f}",
      f"{err.get('translation_mean', 0):.4f}", f"{err.get('rotation_mean_deg', 0):.3f}", f"{given.get('translation_mean', 0):.4f}",
      f"{given.get('rotation_mean_deg', 0):.3f}", f"{p.get('time_offset_s', 0):.4f}", f"{secs:.0f}", threads]))
PY
        tail -1 "$CSV"
      done
    done
  done
done
echo "wrote $CSV"
if [ -n "$RESULTS" ]; then
  cp "$CSV" "$RESULTS/poses.csv"
  python3 bench/results.py
fi
