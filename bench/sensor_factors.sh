#!/usr/bin/env bash
# What each effect of a real sensor costs: one random scene (`simulate random --seed SCENE`) recorded by an
# ideal sensor with one effect of the random sensor added at a time, then by the realistic and the random
# sensor whole, each trained with the default preset and steps (training seed 1, the refractory period learned)
# and, where the sensor has a period, once more with `train --refractory` set to it; ours against both
# baselines under eval's default alignment, and the period each run ended with. The effects' values are those `--sensor random` draws for scene 2 (hand-held): C+ 0.172
# and C- 0.218, 4.4 % mismatch, 0.76 Hz background with 10 hot pixels, 47 µs jitter, 0.75 ms refractory
# period; the refractory period also at 0.1 and 0.3 ms; then the DAVIS-like sensor (`--sensor davis`, the
# realistic sensor with a 1.5 ms period). Writes $OUT/sensor_factors.csv, copies it to bench/results/
# (RESULTS; empty: not copied) and regenerates docs/results.md. About 4 minutes a row on 2 cores.
# Usage: bench/sensor_factors.sh [ROW ...]   (default: every row below)
# Environment: SCENE (2), SEED (training seed, 1), THREADS (2), OUT (out/sensor_factors), BUILD (build),
#              EVNERF (the binary: $BUILD/examples/evnerf), KEEP=1 (reuse rows whose evaluation exists),
#              TRAIN_FLAGS (more train options for every row, split at spaces; not in the CSV's flags).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-out/sensor_factors}
SCENE=${SCENE:-2}
SEED=${SEED:-1}
THREADS=${THREADS:-2}
. bench/evnerf_bin.sh  # EV
# Each row: name | what it is | simulate's sensor flags | train's extra flags ('@' stands for the recording's
# own refractory period, from its sensor_model.txt).
ROWS=(
  "ideal|ideal sensor|--sensor ideal|"
  "thresholds|C+ 0.172, C- 0.218|--sensor ideal --threshold-pos 0.172 --threshold-neg 0.2184|"
  "mismatch|4.4 % threshold mismatch|--sensor ideal --mismatch 0.044|"
  "noise|0.76 Hz background, 10 hot pixels|--sensor ideal --noise-rate 0.76 --hot-pixels 10|"
  "jitter|47 µs timestamp jitter|--sensor ideal --jitter 0.000047|"
  "refractory0.1|0.1 ms refractory period|--sensor ideal --refractory 0.0001|"
  "refractory0.1-r|0.1 ms refractory period, train --refractory|--sensor ideal --refractory 0.0001|--refractory @"
  "refractory0.3|0.3 ms refractory period|--sensor ideal --refractory 0.0003|"
  "refractory0.3-r|0.3 ms refractory period, train --refractory|--sensor ideal --refractory 0.0003|--refractory @"
  "refractory0.75|0.75 ms refractory period|--sensor ideal --refractory 0.00075|"
  "refractory0.75-r|0.75 ms refractory period, train --refractory|--sensor ideal --refractory 0.00075|--refractory @"
  "realistic|the realistic sensor|--sensor realistic|"
  "realistic-r|the realistic sensor, train --refractory|--sensor realistic|--refractory @"
  "random|the random sensor|--sensor random|"
  "random-r|the random sensor, train --refractory|--sensor random|--refractory @"
  "davis|the DAVIS-like sensor|--sensor davis|"
  "davis-r|the DAVIS-like sensor, train --refractory|--sensor davis|--refractory @"
)
read -r -a TRAIN_EXTRA <<<"${TRAIN_FLAGS:-}"
WANT=("$@")
mkdir -p "$OUT"
CSV="$OUT/sensor_factors.csv"
echo "scene_seed,row,what,train_flags,events,psnr,ssim,di_psnr,di_ssim,hpf_psnr,hpf_ssim,period_us" > "$CSV"
for spec in "${ROWS[@]}"; do
  IFS='|' read -r name what sim_flags train_flags <<<"$spec"
  if [ ${#WANT[@]} -gt 0 ] && [[ " ${WANT[*]} " != *" $name "* ]]; then continue; fi
  dir="$OUT/$name"
  scene="$OUT/scene-${sim_flags// /_}"  # rows of the same sensor share its recording
  mkdir -p "$dir"
  read -r -a SIM <<<"$sim_flags"
  [ -f "$scene/events.txt" ] || "$EV" simulate random --seed "$SCENE" "${SIM[@]}" --out "$scene" > "$dir/simulate.txt" 2>&1
  refractory=$(awk '$1 == "refractory" {print $2}' "$scene/sensor_model.txt")
  read -r -a EXTRA <<<"${train_flags//@/$refractory}"
  if [ "${KEEP:-0}" != 1 ] || [ ! -f "$dir/eval/metrics.json" ]; then
    rm -rf "$dir/run" "$dir/eval"
    "$EV" train "$scene" --out "$dir/run" --seed "$SEED" --threads "$THREADS" --quiet --allow-collapse "${EXTRA[@]}" "${TRAIN_EXTRA[@]}" > "$dir/train.txt" 2>&1
    "$EV" eval "$dir/run/model.ckpt" "$scene" --out "$dir/eval" > "$dir/eval.txt" 2>&1
  fi
  python3 - "$dir" "$scene" "$SCENE" "$name" "$what" "${EXTRA[*]}" >> "$CSV" <<'PY'
import csv, json, sys
d, scene, n, name, what, flags = sys.argv[1:]
m = json.load(open(f"{d}/eval/metrics.json"))["methods"]
ours = m[next(k for k in m if k.startswith("evnerf"))]
di, hpf = m["direct_integration"], m["high_pass_filter"]
events = sum(1 for _ in open(f"{scene}/events.txt"))
last = [json.loads(l) for l in open(f"{d}/run/log.jsonl")][-1]  # the period the run ended with (learned or given)
period = f"{last['refractory'] * 1e6:.1f}" if "refractory" in last else "0"
csv.writer(sys.stdout, lineterminator="\n").writerow([n, name, what, flags, events, f"{ours['psnr']:.2f}", f"{ours['ssim']:.3f}", f"{di['psnr']:.2f}",
                                                   f"{di['ssim']:.3f}", f"{hpf['psnr']:.2f}", f"{hpf['ssim']:.3f}", period])
PY
  tail -n 1 "$CSV"
done
RESULTS=${RESULTS-bench/results}
if [ -n "$RESULTS" ]; then
  cp "$CSV" "$RESULTS/sensor_factors.csv"
  echo "copied to $RESULTS/sensor_factors.csv"
  python3 bench/results.py
fi
