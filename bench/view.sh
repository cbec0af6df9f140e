#!/usr/bin/env bash
# `evnerf view`'s frame rate, the field beside the Gaussians started from it: the built-in `object` scene
# recorded at 346 × 260 (a DAVIS346's sensor, as the mesh suite's) trained by the default preset, then by `splat --start-from` that field; each served by
# `evnerf view` and asked for frames by a client that does what the page does (bench/view_client.py): the
# camera orbits the scene's focus by 1° a frame, one frame in flight, each at the resolution the page asks
# for while moving (info's moving_scale), then the camera rests and the full-resolution frame is timed.
# The two viewers take turns (REPS rounds, A B A B); a round's frames a second is frames over the wall time
# the client waited (HTTP, render, JPEG), its server milliseconds the median of X-Frame-Ms. Writes
# $OUT/view.csv, copies it to bench/results/view.csv (RESULTS; empty: not copied) and regenerates
# docs/results.md.
# Usage: bench/view.sh
# Environment: SEED (1), THREADS (2), REPS (3), FRAMES (60: frames per round while moving), OUT (out/view),
#              BUILD, EVNERF.
set -euo pipefail
cd "$(dirname "$0")/.."
SEED=${SEED:-1}
THREADS=${THREADS:-2}
REPS=${REPS:-3}
FRAMES=${FRAMES:-60}
OUT=${OUT:-out/view}
RESULTS=${RESULTS-bench/results}
. bench/evnerf_bin.sh  # EV
scripts/deps.sh python3-numpy
mkdir -p "$OUT"
[ -f "$OUT/rec/events.txt" ] || "$EV" simulate object --width 346 --height 260 --out "$OUT/rec" > "$OUT/simulate.txt" 2>&1
[ -f "$OUT/fast/model.ckpt" ] ||
  "$EV" train "$OUT/rec" --out "$OUT/fast" --seed "$SEED" --threads "$THREADS" --quiet > "$OUT/fast.txt" 2>&1
[ -f "$OUT/splat/model.ckpt" ] ||
  "$EV" train "$OUT/rec" --out "$OUT/splat" --preset splat --start-from "$OUT/fast/model.ckpt" --seed "$SEED" --threads "$THREADS" \
    --quiet > "$OUT/splat.txt" 2>&1
pids=()
trap 'for p in "${pids[@]}"; do kill "$p" 2> /dev/null || true; done' EXIT
declare -A PORT
for p in fast splat; do
  OMP_NUM_THREADS=$THREADS "$EV" view "$OUT/$p/model.ckpt" --port 0 > "$OUT/view_$p.txt" 2>&1 &
  pids+=($!)
  for _ in $(seq 1 600); do
    PORT[$p]=$(grep -o '127\.0\.0\.1:[0-9]*' "$OUT/view_$p.txt" | head -1 | cut -d: -f2 || true)
    [ -n "${PORT[$p]}" ] && break
    sleep 0.2
  done
  [ -n "${PORT[$p]}" ] || { echo "view $p did not start: $(cat "$OUT/view_$p.txt")" >&2; exit 1; }
done
for r in $(seq "$REPS"); do
  for p in fast splat; do
    /usr/bin/python3 bench/view_client.py "${PORT[$p]}" "$FRAMES" > "$OUT/round_${p}_$r.json"
  done
done
/usr/bin/python3 - "$OUT" "$REPS" "$THREADS" "$SEED" > "$OUT/view.csv" <<'PY'
import json, statistics, sys
out, reps, threads, seed = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
print("scene,preset,seed,threads,width,height,moving_width,moving_height,reps,moving_fps,moving_fps_min,moving_fps_max,moving_server_ms,"
      "rest_ms,rest_ms_min,rest_ms_max")
for p in ("fast", "splat"):
    rounds = [json.load(open(f"{out}/round_{p}_{r}.json")) for r in range(1, reps + 1)]
    fps = [r["moving_fps"] for r in rounds]
    rest = [r["rest_ms"] for r in rounds]
    f = rounds[0]
    print(f"object,{p},{seed},{threads},{f['width']},{f['height']},{f['moving_width']},{f['moving_height']},{reps},"
          f"{statistics.median(fps):.1f},{min(fps):.1f},{max(fps):.1f},{statistics.median(r['moving_server_ms'] for r in rounds):.1f},"
          f"{statistics.median(rest):.0f},{min(rest):.0f},{max(rest):.0f}")
PY
cat "$OUT/view.csv"
if [ -n "$RESULTS" ]; then mkdir -p "$RESULTS" && cp "$OUT/view.csv" "$RESULTS/view.csv" && python3 bench/results.py; fi
