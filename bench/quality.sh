#!/usr/bin/env bash
# The quality suite of docs/results.md: each row simulates a recording (or reads a real one), trains the
# row's preset at train's default steps, and scores it with eval against the recording's frames under eval's
# default alignment (global-log-affine; per channel for colour), next to direct integration and the
# high-pass filter. Writes $OUT/quality.csv (one line per row, seed and method, with the training seconds
# and the CPU's vector features), copies it to bench/results/, makes bench/results/montage.png (truth |
# ours | both baselines for planes, object and room at seed 1) and regenerates docs/results.md and the
# README's table from bench/results (bench/results.py).
# Usage: bench/quality.sh [ROW[:SEEDS]…]   for example `planes:1,2,3 room`; without arguments every row of
#        the default list below at its default seeds. About 70 minutes on 2 cores for the whole list.
# Rows: planes object room (the built-in scenes), hdr (`object --hdr`, scored against the linear truth),
#       noise0.5 noise0.9 (planes with random events added at that ratio of the signal), holdout (planes
#       with every 5th boundary held out, scored on the novel views alone), slider (the real IJRR chunk in
#       ../shared/data, `--near 0.1 --far 5`; skipped when absent), blocks (the colour scene, colour
#       preset), blocks-per-channel (the paper's colour method: `train --per-channel`, 1 thread), no-joint
#       no-noise fast-no-tv (the ablation: planes with that preset), splat splat-object splat-room (the
#       Gaussians: planes, object, room with the splat preset, beside fast's rows of the same scenes),
#       splat-field splat-field-object splat-field-room (the Gaussians started from and taught by the field
#       of fast's row of that scene and seed, `train --start-from`: run the fast row first).
# Environment: THREADS (2: a run's bits depend on its thread count), BUILD (build), EVNERF (the binary,
#              $BUILD/examples/evnerf), OUT (out/quality), KEEP (1: a row and seed whose metrics.json is
#              in OUT is not run again), RESULTS (bench/results; empty: nothing copied or regenerated),
#              TRAIN_FLAGS (more train options for every row, split at spaces).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-out/quality}
THREADS=${THREADS:-2}
KEEP=${KEEP:-0}
RESULTS=${RESULTS-bench/results}
. bench/evnerf_bin.sh  # EV
read -r -a TRAIN_EXTRA <<<"${TRAIN_FLAGS:-}"
scripts/deps.sh python3-pil
DEFAULT=(planes:1,2,3 object:1,2,3 room:1 hdr:1 noise0.9:1 slider:1,2,3 blocks:1,2 blocks-per-channel:1,2 no-joint:1,2,3 no-noise:1,2,3
         fast-no-tv:1,2,3)
ROWS=("$@")
[ ${#ROWS[@]} -gt 0 ] || ROWS=("${DEFAULT[@]}")
SLIDER=../shared/data/ijrr_slider_depth_chunk
if grep -qw avx512f /proc/cpuinfo; then CPU=avx512; elif grep -qw avx2 /proc/cpuinfo && grep -qw fma /proc/cpuinfo; then CPU=avx2+fma; else CPU=sse; fi
mkdir -p "$OUT"

# The recording of a row (simulated once into $OUT/<row>/recording), its preset and its train and eval flags.
setup() {
  local r=$1 sim=()
  PRESET=fast TRAIN=() EVAL=() REC="$OUT/$r/recording"
  case "$r" in
    planes|object|room) sim=("$r") ;;
    hdr) sim=(object --hdr) ;;
    noise*) sim=(planes --noise-ratio "${r#noise}") ;;
    holdout) sim=(planes) TRAIN=(--holdout 5) EVAL=(--holdout 5) ;;
    slider) [ -d "$SLIDER" ] || return 1; REC=$SLIDER TRAIN=(--near 0.1 --far 5) ;;
    blocks) sim=(blocks) PRESET=colour ;;
    blocks-per-channel) sim=(blocks) TRAIN=(--per-channel) ;;
    no-joint|no-noise|fast-no-tv) sim=(planes) PRESET=$r ;;
    splat) sim=(planes) PRESET=splat ;;
    splat-object|splat-room) sim=("${r#splat-}") PRESET=splat ;;
    splat-field|splat-field-object|splat-field-room)  # the recording and field of fast's row; @SEED@ is the seed's
      local scene=${r#splat-field-}
      [ "$scene" = splat-field ] && scene=planes
      REC="$OUT/$scene/recording" PRESET=splat TRAIN=(--start-from "$OUT/$scene/seed@SEED@/run/model.ckpt")
      [ -f "$REC/events.txt" ] || { echo "quality: $r needs the $scene row first" >&2; exit 2; } ;;
    *) echo "quality: unknown row '$r'" >&2; exit 2 ;;
  esac
  if [ ${#sim[@]} -gt 0 ] && [ ! -f "$REC/events.txt" ]; then
    "$EV" simulate "${sim[@]}" --out "$REC" > "$OUT/$r/simulate.txt" 2>&1 || { cat "$OUT/$r/simulate.txt"; exit 1; }
  fi
  return 0
}

for spec in "${ROWS[@]}"; do
  r=${spec%%:*}
  seeds=1
  [ "$spec" = "$r" ] || seeds=${spec#*:}
  mkdir -p "$OUT/$r"
  if ! setup "$r"; then echo "$r: $SLIDER absent, skipped"; continue; fi
  for s in ${seeds//,/ }; do
    dir="$OUT/$r/seed$s"
    if [ "$KEEP" = 1 ] && [ -f "$dir/eval/metrics.json" ]; then echo "$r seed $s: kept"; continue; fi
    rm -rf "$dir"
    mkdir -p "$dir"
    threads=$THREADS
    [ "$r" = blocks-per-channel ] && threads=1  # one model per channel; its bits as measured with 1 thread
    train=("${TRAIN[@]//@SEED@/$s}")
    "$EV" train "$REC" --out "$dir/run" --preset "$PRESET" --seed "$s" --threads "$threads" --quiet "${train[@]}" "${TRAIN_EXTRA[@]}" \
      > "$dir/train.txt" 2>&1 || { cat "$dir/train.txt"; exit 1; }
    model="$dir/run/model.ckpt"
    [ -f "$model" ] || model="$dir/run/channels.json"
    "$EV" eval "$model" "$REC" --out "$dir/eval" "${EVAL[@]}" > "$dir/eval.txt" 2>&1 || { cat "$dir/eval.txt"; exit 1; }
    echo "$r seed $s: $(awk '/^evnerf/ {print $3 " dB / " $4; exit}' "$dir/eval.txt"), $(grep -o 'steps in [0-9.]* s' "$dir/train.txt" | head -1)"
  done
done

# One CSV line per row, seed and method, from every row in OUT (so rows run at different times gather).
python3 - "$OUT" "$CPU" "$THREADS" <<'PY' > "$OUT/quality.csv"
import json, os, re, sys
out, cpu, threads = sys.argv[1:]
print("row,seed,preset,steps,threads,alignment,truth,method,psnr,ssim,oracle_both_psnr,train_seconds,cpu")
for row in sorted(os.listdir(out)):
    d = os.path.join(out, row)
    if not os.path.isdir(d):
        continue
    for seed in sorted((s for s in os.listdir(d) if s.startswith("seed")), key=lambda s: int(s[4:])):
        f = os.path.join(d, seed, "eval", "metrics.json")
        if not os.path.exists(f):
            continue
        m = json.load(open(f))
        settings = os.path.join(d, seed, "run", "settings.json")
        if not os.path.exists(settings):  # --per-channel: one run per channel, the same settings
            settings = os.path.join(d, seed, "run", "g", "settings.json")
        j = json.load(open(settings))
        cfg = j["runs"][-1]
        train = open(os.path.join(d, seed, "train.txt")).read()
        secs = sum(float(x) for x in re.findall(r" steps in ([0-9.]+) s", train))
        methods = m["heldout"]["methods"] if row == "holdout" else m["methods"]
        scales = m.get("error_scales", {}).get("methods", {})
        for name, v in methods.items():
            method = "ours" if name.startswith("evnerf") else name
            oracle = scales.get(name, {}).get("oracle_both_psnr")  # eval's row and column offset oracle: a diagnosis
            print(f"{row},{seed[4:]},{j['variant']},{cfg['iterations']},{cfg['threads']},{m['alignment']},"
                  f"{m.get('truth', {}).get('kind', 'frames')},{method},{v['psnr']:.2f},{v['ssim']:.3f},"
                  f"{'' if oracle is None else f'{oracle:.2f}'},{secs:.1f},{cpu}")
PY
echo "wrote $OUT/quality.csv"
if [ -n "$RESULTS" ]; then
  mkdir -p "$RESULTS"
  cp "$OUT/quality.csv" "$RESULTS/quality.csv"
  shots=()
  for r in planes object room; do [ -f "$OUT/$r/seed1/eval/montage.png" ] && shots+=("$r" "$OUT/$r/seed1/eval/montage.png"); done
  [ ${#shots[@]} -eq 0 ] || /usr/bin/python3 bench/montage.py "$RESULTS/montage.png" "${shots[@]}"
  python3 bench/results.py --results "$RESULTS"
fi
