#!/usr/bin/env bash
# The mesh suite: the field's object-centric benchmark on real 3-D assets from Debian's assimp-testmodels.
# Each asset is recorded by `evnerf simulate mesh` (346 × 260, one revolution of EventNeRF's orbit at 30°,
# held-out views on a second orbit at 50°), grey and through an RGGB mosaic (`--bayer`), trained at the
# default steps (grey: the default preset; colour: the `colour` preset) and scored by `evnerf eval` on the
# training path (against both baselines) and on the held-out views (ours only), under the global log-affine
# fit (eval's default), EventNeRF's fit and the offset-only log correction (E-3DGS's). Writes
# $OUT/mesh.csv, merges it into bench/results/mesh.csv (its rows replace those of the same asset, mode and
# preset) with a montage per asset of the default presets (bench/results/mesh/) and regenerates
# docs/results.md (bench/results.py).
# Usage: bench/mesh_suite.sh [ASSET…]   (default: all six of ASSETS below; ASSET is a key of that table)
# Environment: MODES ("grey colour"), THREADS (2), SEEDS (training seeds, "1 2": each asset and mode is recorded once and
#              trained once per seed, in OUT/<asset>-<mode>/s<seed>), STEPS (train's default),
#              PRESET_GREY (fast), PRESET_COLOUR (colour): the variants trained (with EVNERF, a program's own),
#              BACKGROUND (empty: none; 0.5: train knows simulate mesh's grey backdrop, as EventNeRF's runs
#              know theirs), DEPTHS (empty: train's near and far; "1.5 4.5": where the object can lie seen
#              from the orbit, radius 3 ± 1.5), START_FROM (an OUT of an earlier run of the default preset: each
#              run starts from its field, `train --start-from OUT/<asset>-<mode>/s<seed>/run/model.ckpt`, and is
#              recorded as preset `<preset>-from-field`), TRAIN_FLAGS (more train options, split at spaces), BUILD
#              (build), EVNERF (the binary), OUT (out/mesh), KEEP (1:
#              an asset and mode whose metrics.json is in OUT is not run again), RESULTS (bench/results;
#              empty: not copied).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-out/mesh}
THREADS=${THREADS:-2}
read -r -a SEEDS <<<"${SEEDS:-1 2}"
KEEP=${KEEP:-0}
RESULTS=${RESULTS-bench/results}
BACKGROUND=${BACKGROUND-}
DEPTHS=${DEPTHS-}
read -r -a TRAIN_EXTRA <<<"${TRAIN_FLAGS:-}"
. bench/evnerf_bin.sh  # EV
scripts/deps.sh assimp-testmodels python3-pil
M=/usr/share/assimp/models
# key, kind, file under $M: a textured animal, a character, two vehicles, a mechanical part without
# texture, a thin-structured object.
ASSETS="duck animal Collada/duck.dae
mrfixit character IQM/mrfixit.iqm
milktruck vehicle glTF/CesiumMilkTruck/CesiumMilkTruck.gltf
jeep vehicle MS3D/jeep1.ms3d
engine untextured-mechanical glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb
spider thin-legged OBJ/spider.obj"
read -r -a MODES <<<"${MODES:-grey colour}"
WANT=("$@")
if grep -qw avx512f /proc/cpuinfo; then CPU=avx512; elif grep -qw avx2 /proc/cpuinfo && grep -qw fma /proc/cpuinfo; then CPU=avx2+fma; else CPU=sse; fi
mkdir -p "$OUT"
CSV="$OUT/mesh.csv"
echo "asset,kind,mode,preset,steps,threads,seed,background,near,far,cpu,events,simulate_seconds,train_seconds,samples_per_ray,view,alignment,method,psnr,ssim" > "$CSV"
while read -r key kind file; do
  if [ ${#WANT[@]} -gt 0 ] && [[ ! " ${WANT[*]} " == *" $key "* ]]; then continue; fi
  for mode in "${MODES[@]}"; do
    dir="$OUT/$key-$mode"
    flags=()
    preset=${PRESET_GREY:-fast}
    if [ "$mode" = colour ]; then flags=(--bayer); preset=${PRESET_COLOUR:-colour}; fi
    mkdir -p "$dir"
    if [ "$KEEP" != 1 ] || [ ! -f "$dir/rec/events.txt" ]; then
      rm -rf "$dir/rec"
      /usr/bin/time -f "%e" -o "$dir/simulate.seconds" "$EV" simulate mesh "$M/$file" "${flags[@]}" --out "$dir/rec" > "$dir/simulate.txt" 2>&1
    fi
    for seed in "${SEEDS[@]}"; do
      run="$dir/s$seed"
      if [ "$KEEP" != 1 ] || [ ! -f "$run/eval/metrics.json" ]; then
        rm -rf "$run"
        mkdir -p "$run"
        train=(--preset "$preset" --seed "$seed" --threads "$THREADS" --quiet --allow-collapse)
        [ -n "${STEPS:-}" ] && train+=(--iterations "$STEPS")
        [ -n "$BACKGROUND" ] && train+=(--background "$BACKGROUND")
        [ -n "$DEPTHS" ] && train+=(--near "${DEPTHS% *}" --far "${DEPTHS#* }")
        [ -n "${START_FROM:-}" ] && train+=(--start-from "$START_FROM/$key-$mode/s$seed/run/model.ckpt")
        train+=("${TRAIN_EXTRA[@]}")
        "$EV" train "$dir/rec" --out "$run/run" "${train[@]}" > "$run/train.txt" 2>&1
        "$EV" eval "$run/run/model.ckpt" "$dir/rec" --out "$run/eval" > "$run/eval.txt" 2>&1
      fi
      label=$preset
      [ -n "${START_FROM:-}" ] && label=$preset-from-field
      python3 - "$dir" "$run" "$key" "$kind" "$mode" "$label" "$THREADS" "$seed" "$CPU" >> "$CSV" <<'PY'
import json, sys
d, run, key, kind, mode, preset, threads, seed, cpu = sys.argv[1:]
st = json.load(open(f"{run}/run/settings.json"))["runs"][-1]
bg = st["background"] if st["background"] is not None else "learned" if st.get("learn_background") else ""
m = json.load(open(f"{run}/eval/metrics.json"))
log = [json.loads(l) for l in open(f"{run}/run/log.jsonl")]
spr = [r["samples_per_ray"] for r in log if "samples_per_ray" in r]
train = open(f"{run}/train.txt").read()
steps = train.split("trained ")[1].split(": ")[1].split(" steps")[0] if "trained " in train else "nan"
secs = train.split(" steps in ")[1].split(" s")[0] if " steps in " in train else "nan"
sim = open(f"{d}/simulate.seconds").read().split()[-1]
events = sum(1 for _ in open(f"{d}/rec/events.txt"))
def rows(j):  # metrics.json: the primary alignment, the secondary, the others
    yield j["alignment"], j["methods"]
    for o in ([j["secondary"]] if "secondary" in j else []) + j.get("other_alignments", []):
        yield o["alignment"], o["methods"]
for view, j in (("path", m), ("novel", m["novel_views"])):
    for al, methods in rows(j):
        if al not in ("global-log-affine", "eventnerf", "global-log-offset"):
            continue
        for name, s in methods.items():
            method = "ours" if name.startswith("evnerf") else name
            print(f"{key},{kind},{mode},{preset},{steps},{threads},{seed},{bg},{st['near']},{st['far']},{cpu},{events},{sim},{secs},"
                  f"{spr[-1] if spr else float('nan'):.1f},{view},{al},{method},{s['psnr']:.2f},{s['ssim']:.3f}")
PY
      echo "$key $mode seed $seed: $(grep "^$key,.*,$mode,.*,$seed,.*,global-log-affine," "$CSV" | cut -d, -f16- | tr '\n' ' ')"
    done
  done
done <<<"$ASSETS"
if [ -n "$RESULTS" ]; then
  mkdir -p "$RESULTS/mesh"
  # The rows of this run replace those of the same asset, mode and preset; the others stay (a run of one
  # preset, `PRESET_GREY=splat` say, keeps the default preset's rows beside it).
  python3 - "$CSV" "$RESULTS/mesh.csv" <<'PY'
import csv, os, sys
new, kept = sys.argv[1:]
rows = list(csv.DictReader(open(new)))
keys = {(r["asset"], r["mode"], r["preset"]) for r in rows}
old = [r for r in csv.DictReader(open(kept)) if (r["asset"], r["mode"], r["preset"]) not in keys] if os.path.exists(kept) else []
with open(kept + ".tmp", "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0].keys()) if rows else [], lineterminator="\n")
    w.writeheader()
    w.writerows(old + rows)
os.replace(kept + ".tmp", kept)
PY
  for dir in "$OUT"/*-grey "$OUT"/*-colour; do
    ev="$dir/s${SEEDS[0]}/eval"  # the first seed's montages, the default presets' only
    [ "${PRESET_GREY:-fast}" = fast ] || [[ "$dir" == *-colour ]] || continue
    [ "${PRESET_COLOUR:-colour}" = colour ] || [[ "$dir" == *-grey ]] || continue
    [ -f "$ev/montage.png" ] || continue
    n=$(basename "$dir")
    /usr/bin/python3 - "$ev/montage.png" "$ev/montage_novel.png" "$RESULTS/mesh/$n.png" <<'PY'
import sys
from PIL import Image
a, b = (Image.open(p).convert("RGB") for p in sys.argv[1:3])
out = sys.argv[3]
# The training path's truth | ours | direct integration | high-pass filter above the held-out view's truth | ours,
# at half size: the picture stays small in the repository.
o = Image.new("RGB", (a.width, a.height + b.height + 2), "white")
o.paste(a, (0, 0))
o.paste(b, (0, a.height + 2))
o.resize((o.width // 2, o.height // 2), Image.LANCZOS).save(out, optimize=True)
PY
  done
  python3 bench/results.py
fi
