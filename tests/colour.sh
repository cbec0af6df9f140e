#!/usr/bin/env bash
# Colour evaluation: on a simulated Bayer recording, `eval` of the colour preset scores in RGB
# ("channels": 3, per-channel alignment, grey scores under "grey", an RGB montage), `baselines` too (each
# pixel's own events integrated, then demosaiced); the grey preset on the same recording is scored in grey.
# ctest runs this as cli.colour. Usage: tests/colour.sh EVNERF_BINARY
set -euo pipefail
EV=$1
work=$(mktemp -d "${TMPDIR:-/tmp}/evnerf_colour.XXXXXX")
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
"$EV" simulate object --bayer --out "$work/rec" --width 32 --height 24 > /dev/null 2>&1
ARGS=(--iters 20 --pixels 256 --seed 1 --threads 2 --quiet --allow-collapse)
"$EV" train "$work/rec" --out "$work/colour" --preset colour "${ARGS[@]}" > /dev/null 2>&1
"$EV" train "$work/rec" --out "$work/grey" --preset fast "${ARGS[@]}" > /dev/null 2>&1
"$EV" eval "$work/colour/model.ckpt" "$work/rec" --out "$work/eval_colour" > /dev/null 2>&1
"$EV" eval "$work/grey/model.ckpt" "$work/rec" --out "$work/eval_grey" > /dev/null 2>&1
"$EV" baselines "$work/rec" --out "$work/base" > /dev/null 2>&1
python3 - "$work" <<'PY' || fail "colour evaluation"
import json, struct, sys
w = sys.argv[1]
def png_colour_type(path):  # IHDR: width, height, bit depth, colour type (2 = RGB, 0 = grey)
    b = open(path, "rb").read(26)
    return b[25]
c = json.load(open(f"{w}/eval_colour/metrics.json"))
assert c["channels"] == 3 and "grey" in c, "colour preset on a colour recording: RGB scores and grey secondary"
assert set(c["methods"]) == {"evnerf_colour", "direct_integration", "high_pass_filter"}
assert set(c["grey"]["methods"]) == set(c["methods"])
assert png_colour_type(f"{w}/eval_colour/montage.png") == 2, "the montage is in colour"
g = json.load(open(f"{w}/eval_grey/metrics.json"))
assert g["channels"] == 1 and "grey" not in g, "a grey model is scored in grey"
assert png_colour_type(f"{w}/eval_grey/montage.png") == 0
b = json.load(open(f"{w}/base/baselines.json"))
assert b["channels"] == 3, "baselines on a colour recording are scored in colour"
for m in ("direct_integration", "high_pass_filter"):
    assert 0 < b["methods"][m]["psnr"] < 100 and 0 < c["methods"][m]["psnr"] < 100, m
PY
echo "colour: eval and baselines score a Bayer recording in RGB (grey secondary); a grey model in grey"
