#!/usr/bin/env bash
# A whole view's render time, Gaussians beside the field: one asset of the mesh suite recorded by `evnerf
# simulate mesh` (346 × 260), trained by each preset of PRESETS with its defaults, then scored by `evnerf eval`
# REPS times, the presets alternating (A B A B …) so that both see the same machine. eval renders every frame
# of the training path and every held-out view and reports its seconds per render; the median over the
# repetitions is the preset's time, and the ratio to the first preset's is taken per repetition (the ratio's
# median and range are written). Beside each time: the held-out views' and the path's PSNR (global-log-affine),
# so a time comes with the quality it renders. Writes $OUT/render.csv, copies it to bench/results/render.csv
# (RESULTS; empty: not copied) and regenerates docs/results.md.
# Usage: bench/render.sh [ASSET]   (a key of bench/mesh_suite.sh's table; default duck)
# Environment: PRESETS ("fast splat"), SEED (1), THREADS (2), REPS (5), OUT (out/render), BUILD, EVNERF.
set -euo pipefail
cd "$(dirname "$0")/.."
ASSET=${1:-duck}
read -r -a PRESETS <<<"${PRESETS:-fast splat}"
SEED=${SEED:-1}
THREADS=${THREADS:-2}
REPS=${REPS:-5}
OUT=${OUT:-out/render}
RESULTS=${RESULTS-bench/results}
. bench/evnerf_bin.sh  # EV
scripts/deps.sh assimp-testmodels
file=$(sed -n "s/^\(ASSETS=\"\)\?$ASSET [^ ]* //p" bench/mesh_suite.sh | tr -d '"')
[ -n "$file" ] || { echo "render: '$ASSET' is not an asset of bench/mesh_suite.sh" >&2; exit 2; }
mkdir -p "$OUT"
rm -rf "$OUT/rec"
"$EV" simulate mesh "/usr/share/assimp/models/$file" --out "$OUT/rec" > "$OUT/simulate.txt" 2>&1
for p in "${PRESETS[@]}"; do
  rm -rf "${OUT:?}/$p" && mkdir -p "$OUT/$p"
  "$EV" train "$OUT/rec" --out "$OUT/$p/run" --preset "$p" --seed "$SEED" --threads "$THREADS" --quiet --allow-collapse > "$OUT/$p/train.txt" 2>&1
done
for r in $(seq "$REPS"); do
  for p in "${PRESETS[@]}"; do
    OMP_NUM_THREADS=$THREADS "$EV" eval "$OUT/$p/run/model.ckpt" "$OUT/rec" --out "$OUT/$p/eval_$r" > "$OUT/$p/eval_$r.txt" 2>&1
  done
done
python3 - "$OUT" "$ASSET" "$SEED" "$THREADS" "$REPS" "${PRESETS[@]}" > "$OUT/render.csv" <<'PY'
import json, statistics, sys
out, asset, seed, threads, reps, *presets = sys.argv[1:]
reps = int(reps)
def metrics(p, r):
    return json.load(open(f"{out}/{p}/eval_{r}/metrics.json"))
def ours(j):
    return next(v for k, v in j["methods"].items() if k.startswith("evnerf"))
ms = {p: [1e3 * metrics(p, r)["seconds_per_render"] for r in range(1, reps + 1)] for p in presets}
print("asset,preset,seed,threads,width,height,reps,ms_per_view,ms_min,ms_max,ratio_to_first,ratio_min,ratio_max,train_seconds,path_psnr,novel_psnr,alignment")
for p in presets:
    ratio = [ms[presets[0]][i] / ms[p][i] for i in range(reps)]
    train = open(f"{out}/{p}/train.txt").read()
    secs = train.split(" steps in ")[1].split(" s")[0] if " steps in " in train else "nan"
    j = metrics(p, 1)
    size = open(f"{out}/{p}/eval_1.txt").read().split(" render; ")[0].split(" per ")[-1]
    w, h = size.split("x")
    print(f"{asset},{p},{seed},{threads},{w},{h},{reps},{statistics.median(ms[p]):.1f},{min(ms[p]):.1f},{max(ms[p]):.1f},"
          f"{statistics.median(ratio):.2f},{min(ratio):.2f},{max(ratio):.2f},{secs},{ours(j)['psnr']:.2f},"
          f"{ours(j['novel_views'])['psnr']:.2f},{j['alignment']}")
PY
cat "$OUT/render.csv"
if [ -n "$RESULTS" ]; then mkdir -p "$RESULTS" && cp "$OUT/render.csv" "$RESULTS/render.csv" && python3 bench/results.py; fi
