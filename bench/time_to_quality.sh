#!/usr/bin/env bash
# Time to quality: trains a preset on built-in scenes and scores it every EVERY steps (train --resume is
# bit-identical to an uninterrupted run, so the curve is that of one run). Writes $OUT/time_to_quality.csv
# (scene, steps, training seconds, samples per ray forward/backward, PSNR and SSIM of ours and of the best
# baseline under eval's default alignment, global-log-affine) and a PNG plot.
# Usage: bench/time_to_quality.sh [scenes…]   (default: planes room object)
# Environment: PRESET (fast), STEPS (6000), EVERY (500), SEED (1), THREADS (2: a run's bits depend on its
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
PRESET=${PRESET:-fast}
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
echo "scene,preset,seed,steps,train_seconds,samples_per_ray,backward_samples_per_ray,psnr,ssim,best_baseline_psnr,best_baseline_ssim" > "$CSV"
for sc in "${SCENES[@]}"; do
  dir="$OUT/$sc"
  rm -rf "$dir"
  "$EV" simulate "$sc" --out "$dir/scene" > /dev/null 2>&1
  total=0
  for ((s = EVERY; s <= STEPS; s += EVERY)); do
    "$EV" train "$dir/scene" --preset "$PRESET" --iterations "$s" --seed "$SEED" --threads "$THREADS" --out "$dir/run" --resume --quiet "${TRAIN_EXTRA[@]}" > "$dir/train.txt" 2>&1
    secs=$(sed -n 's/.* steps in \([0-9.]*\) s.*/\1/p' "$dir/train.txt")
    total=$(python3 -c "print($total + $secs)")
    "$EV" eval "$dir/run/model.ckpt" "$dir/scene" --out "$dir/eval_$s" > "$dir/eval_$s.txt" 2>&1
    python3 - "$dir" "$s" "$total" "$sc" "$PRESET" "$SEED" >> "$CSV" <<'PY'
import json, sys
d, s, t, sc, preset, seed = sys.argv[1:]
m = json.load(open(f"{d}/eval_{s}/metrics.json"))["methods"]
ours = next(v for k, v in m.items() if k.startswith("evnerf"))
base = max((v for k, v in m.items() if not k.startswith("evnerf")), key=lambda v: v["psnr"])
log = [json.loads(l) for l in open(f"{d}/run/log.jsonl")]
spr = sum(l["samples_per_ray"] for l in log) / len(log)
bpr = sum(l["backward_samples_per_ray"] for l in log) / len(log)
print(f"{sc},{preset},{seed},{s},{float(t):.1f},{spr:.1f},{bpr:.1f},{ours['psnr']:.3f},{ours['ssim']:.4f},{base['psnr']:.3f},{base['ssim']:.4f}")
PY
    tail -1 "$CSV"
  done
done
/usr/bin/python3 - "$CSV" "$OUT/$NAME.png" <<'PY'
import csv, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
rows = list(csv.DictReader(open(sys.argv[1])))
fig, ax = plt.subplots(1, 2, figsize=(10, 4))
for sc in dict.fromkeys(r["scene"] for r in rows):
    rs = [r for r in rows if r["scene"] == sc]
    t = [float(r["train_seconds"]) / 60 for r in rs]
    for k, (col, name) in enumerate([("psnr", "PSNR (dB)"), ("ssim", "SSIM")]):
        line, = ax[k].plot(t, [float(r[col]) for r in rs], marker="o", label=f"{sc} ({rs[0]['preset']})")
        ax[k].axhline(float(rs[-1]["best_baseline_" + col]), color=line.get_color(), ls=":", lw=1)
        ax[k].set_xlabel("training time (min, 2 cores)")
        ax[k].set_ylabel(name + ", global-log-affine")
ax[0].legend()
ax[0].set_title("ours (solid) vs best baseline (dotted)")
fig.tight_layout()
fig.savefig(sys.argv[2], dpi=110)
print("wrote", sys.argv[2])
PY
# The current curve is kept in the repository (RESULTS, default bench/results; empty: not copied).
RESULTS=${RESULTS-bench/results}
if [ -n "$RESULTS" ]; then mkdir -p "$RESULTS" && cp "$CSV" "$OUT/$NAME.png" "$RESULTS/" && echo "copied to $RESULTS/"; fi
