#!/usr/bin/env bash
# Time to quality: trains each preset of PRESETS on built-in scenes and scores it every EVERY steps (train
# --resume is bit-identical to an uninterrupted run, so the curve is that of one run); the presets take turns
# per scene, so that their curves see the same machine. Writes $OUT/time_to_quality.csv (scene, preset, steps,
# training seconds, samples per ray forward/backward, whether a backdrop was learned, PSNR and SSIM of ours
# and of the best baseline under eval's default alignment, global-log-affine) and a PNG plot.
# Usage: bench/time_to_quality.sh [scenes…]   (default: planes room object)
# Environment: PRESETS ("fast splat"), STEPS (6000; STEPS_<preset> for one preset, '-' read as '_': STEPS_splat=15000
# runs the Gaussians past fast's steps, to see where they reach its score), EVERY (500), SEED (1), THREADS (2: a run's bits depend on its
# thread count, so curves compare across machines only at one count), OUT (out/time_to_quality), BUILD (build),
# EVNERF (the binary: $BUILD/examples/evnerf), TRAIN_FLAGS (more train options, split at spaces), ISA (native;
# avx2: the AVX2 + FMA path on a CPU with AVX-512, built in build-avx2, the files named time_to_quality_avx2.*).
set -euo pipefail
cd "$(dirname "$0")/.."
case "${ISA:-native}" in
  native) NAME=time_to_quality ;;
  avx2) NAME=time_to_quality_avx2; NO512=ON; BUILD=${BUILD:-build-avx2} ;;
  *) echo "time_to_quality: ISA is native or avx2, not '$ISA'" >&2; exit 2 ;;
esac
OUT=${OUT:-out/$NAME}
read -r -a PRESETS <<<"${PRESETS:-fast splat}"
STEPS=${STEPS:-6000}
EVERY=${EVERY:-500}
SEED=${SEED:-1}
THREADS=${THREADS:-2}
. bench/evnerf_bin.sh  # EV
read -r -a TRAIN_EXTRA <<<"${TRAIN_FLAGS:-}"
scripts/deps.sh python3-matplotlib
SCENES=("$@")
[ ${#SCENES[@]} -gt 0 ] || SCENES=(planes room object)
mkdir -p "$OUT"
CSV="$OUT/$NAME.csv"
echo "scene,preset,seed,steps,train_seconds,samples_per_ray,backward_samples_per_ray,backdrop,psnr,ssim,best_baseline_psnr,best_baseline_ssim" > "$CSV"
for sc in "${SCENES[@]}"; do
  rm -rf "${OUT:?}/$sc"
  "$EV" simulate "$sc" --out "$OUT/$sc/scene" > /dev/null 2>&1
  for preset in "${PRESETS[@]}"; do
    dir="$OUT/$sc/$preset"
    mkdir -p "$dir"
    total=0
    steps_var="STEPS_${preset//-/_}"
    for ((s = EVERY; s <= ${!steps_var:-$STEPS}; s += EVERY)); do
      "$EV" train "$OUT/$sc/scene" --preset "$preset" --iterations "$s" --seed "$SEED" --threads "$THREADS" --out "$dir/run" --resume --quiet "${TRAIN_EXTRA[@]}" > "$dir/train.txt" 2>&1
      secs=$(sed -n 's/.* steps in \([0-9.]*\) s.*/\1/p' "$dir/train.txt")
      total=$(python3 -c "print($total + $secs)")
      "$EV" eval "$dir/run/model.ckpt" "$OUT/$sc/scene" --out "$dir/eval_$s" > "$dir/eval_$s.txt" 2>&1
      python3 - "$dir" "$s" "$total" "$sc" "$preset" "$SEED" >> "$CSV" <<'PY'
import json, sys
d, s, t, sc, preset, seed = sys.argv[1:]
m = json.load(open(f"{d}/eval_{s}/metrics.json"))["methods"]
ours = next(v for k, v in m.items() if k.startswith("evnerf"))
base = max((v for k, v in m.items() if not k.startswith("evnerf")), key=lambda v: v["psnr"])
log = [json.loads(l) for l in open(f"{d}/run/log.jsonl")]
spr = sum(l["samples_per_ray"] for l in log) / len(log)
bpr = sum(l["backward_samples_per_ray"] for l in log) / len(log)
st = json.load(open(f"{d}/run/settings.json"))["runs"][-1]
backdrop = "learned" if st.get("learn_background") and st.get("background") is None else "given" if st.get("background") is not None else "none"
print(f"{sc},{preset},{seed},{s},{float(t):.1f},{spr:.1f},{bpr:.1f},{backdrop},{ours['psnr']:.3f},{ours['ssim']:.4f},{base['psnr']:.3f},{base['ssim']:.4f}")
PY
      tail -1 "$CSV"
    done
  done
done
/usr/bin/python3 - "$CSV" "$OUT/$NAME.png" <<'PY'
import csv, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
rows = list(csv.DictReader(open(sys.argv[1])))
fig, ax = plt.subplots(1, 2, figsize=(10, 4))
colours, styles = {}, ["-", "--", "-.", ":"]
presets = list(dict.fromkeys(r["preset"] for r in rows))
for sc, preset in dict.fromkeys((r["scene"], r["preset"]) for r in rows):
    rs = [r for r in rows if (r["scene"], r["preset"]) == (sc, preset)]
    t = [float(r["train_seconds"]) / 60 for r in rs]
    for k, (col, name) in enumerate([("psnr", "PSNR (dB)"), ("ssim", "SSIM")]):
        line, = ax[k].plot(t, [float(r[col]) for r in rs], marker="o", color=colours.get(sc), ls=styles[presets.index(preset) % 4],
                           label=f"{sc} ({preset})")
        colours[sc] = line.get_color()
        if preset == presets[0]:
            ax[k].axhline(float(rs[-1]["best_baseline_" + col]), color=line.get_color(), ls=":", lw=1)
        ax[k].set_xlabel("training time (min, 2 cores)")
        ax[k].set_ylabel(name + ", global-log-affine")
ax[0].legend()
ax[0].set_title("ours (one line style per preset) vs best baseline (dotted)")
fig.tight_layout()
fig.savefig(sys.argv[2], dpi=110)
print("wrote", sys.argv[2])
PY
# The current curve is kept in the repository (RESULTS, default bench/results; empty: not copied).
RESULTS=${RESULTS-bench/results}
if [ -n "$RESULTS" ]; then mkdir -p "$RESULTS" && cp "$CSV" "$OUT/$NAME.png" "$RESULTS/" && echo "copied to $RESULTS/"; fi
