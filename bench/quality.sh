#!/usr/bin/env bash
# Quality tables for bench/README.md, each row simulate → train (Fast, ITERS steps) → eval against the
# frames (eval's default alignment, global-log-affine, then per-image log-affine and min-max), next to
# direct integration and the high-pass filter:
#   every built-in scene; the planes scene with random events added at ratios 0.5 and 0.9 of the signal;
#   the planes scene trained with every 5th boundary held out (novel views scored on their own);
#   the real IJRR slider_depth chunk (frames 1–4, when ../shared/data is present).
# About 35 minutes on 2 cores. Usage: bench/quality.sh [rows…]
# Environment: ITERS (1500), PRESET (fast), THREADS (2: a run's bits depend on its thread count, so the
# tables compare across machines only at one count), BUILD (build), OUT (out/quality), EVNERF (the binary:
# $BUILD/examples/evnerf), TRAIN_FLAGS (more train options for every row, split at spaces).
# (rows: planes object room noise0.5 noise0.9 holdout slider)
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${BUILD:-build}
OUT=${OUT:-out/quality}
ITERS=${ITERS:-1500}
PRESET=${PRESET:-fast}
THREADS=${THREADS:-2}
EV="${EVNERF:-$BUILD/examples/evnerf}"
[ -z "${EVNERF:-}" ] || [ -x "$EV" ] || { echo "quality: EVNERF=$EV is not an executable" >&2; exit 2; }
read -r -a TRAIN_EXTRA <<<"${TRAIN_FLAGS:-}"
[ -x "$EV" ] || { scripts/deps.sh; cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null; cmake --build "$BUILD" -j"$(nproc)" --target evnerf_cli; }
ROWS=("$@")
[ ${#ROWS[@]} -gt 0 ] || ROWS=(planes object room noise0.5 noise0.9 holdout slider)

row() {  # name recording-folder eval-args [train args…]
  local name=$1 folder=$2 evargs=$3
  shift 3
  mkdir -p "$OUT/$name"
  "$EV" train "$folder" --preset "$PRESET" --iterations "$ITERS" --threads "$THREADS" --out "$OUT/$name/run" --quiet "${TRAIN_EXTRA[@]}" "$@" > "$OUT/$name/train.log" 2>&1
  "$EV" eval "$OUT/$name/run/model.ckpt" "$folder" --out "$OUT/$name/eval" $evargs | tee "$OUT/$name/eval.txt"
}
for r in "${ROWS[@]}"; do
  case "$r" in
    planes|object|room)
      "$EV" simulate "$r" --out "$OUT/$r/scene" > /dev/null
      row "$r" "$OUT/$r/scene" "" ;;
    holdout)
      "$EV" simulate planes --out "$OUT/$r/scene" > /dev/null
      row "$r" "$OUT/$r/scene" "--holdout 5" --holdout 5 ;;
    noise*)
      ratio=${r#noise}
      "$EV" simulate planes --noise-ratio "$ratio" --out "$OUT/$r/scene" > /dev/null
      row "$r" "$OUT/$r/scene" "" ;;
    slider)
      data=../shared/data/ijrr_slider_depth_chunk
      if [ -d "$data" ]; then row slider "$data" "" --near 0.1 --far 5; else echo "slider: $data absent, skipped"; fi ;;
    *) echo "unknown row $r"; exit 2 ;;
  esac
done
python3 - "$OUT" <<'EOF'
import json, os, sys
out = sys.argv[1]
def fmt(s):
    return f"{s['psnr']:.2f} dB / {s['ssim']:.3f}"
def table(title, pick):
    print(f"\n{title}\n\n| row | evnerf PSNR / SSIM | direct integration | high-pass filter | ours ≥ both + 3 dB and + 0.10 SSIM? |")
    print("|---|---|---|---|---|")
    for name in sorted(os.listdir(out)):
        f = os.path.join(out, name, "eval", "metrics.json")
        if not os.path.exists(f):
            continue
        m = pick(json.load(open(f)))
        if m is None:
            continue
        ours = next(v for k, v in m.items() if k.startswith("evnerf"))
        di, hp = m["direct_integration"], m["high_pass_filter"]
        beats = all(ours["psnr"] >= b["psnr"] + 3 and ours["ssim"] >= b["ssim"] + 0.10 for b in (di, hp))
        print(f"| {name} | {fmt(ours)} | {fmt(di)} | {fmt(hp)} | {'yes' if beats else 'no'} |")
def by(al):
    def pick(j):
        if j["alignment"] == al:
            return j["methods"]
        for o in [j.get("secondary")] + j.get("other_alignments", []):
            if o and o["alignment"] == al:
                return o["methods"]
    return pick
table("global-log-affine alignment (eval's primary: one map over the sequence)", by("global-log-affine"))
table("log-affine alignment (per image)", by("log-affine"))
table("min-max alignment (the spec's)", by("min-max"))
table("held-out frames only (novel views), global-log-affine", lambda j: j["heldout"]["methods"] if "heldout" in j else None)
EOF
