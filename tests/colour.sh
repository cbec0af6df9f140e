#!/usr/bin/env bash
# Colour evaluation: on a simulated Bayer recording, `eval` of the colour preset scores in RGB
# ("channels": 3, per-channel alignment, grey scores under "grey", an RGB montage), `baselines` too (each
# pixel's own events integrated, then demosaiced); the grey preset on the same recording is scored in grey.
# The paper's colour method (train --per-channel: a grey model per channel's quarter-resolution sites)
# writes channels.json, which render and eval take as the checkpoint, reaching the full sensor either way
# (--channel-upsampling volume, sites: equal at the sites); it refuses a colour variant, and a damaged
# channels.json is an error naming the file.
# ctest runs this as cli.colour. Usage: tests/colour.sh EVNERF_BINARY
set -euo pipefail
EV=$1
work=$(mktemp -d "${TMPDIR:-/tmp}/evnerf_colour.XXXXXX")
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
"$EV" simulate object --bayer --out "$work/rec" --width 32 --height 24 > /dev/null 2>&1
ARGS=(--iterations 20 --pixels 256 --seed 1 --threads 2 --quiet --allow-collapse)
"$EV" train "$work/rec" --out "$work/colour" --preset colour "${ARGS[@]}" > /dev/null 2>&1
"$EV" train "$work/rec" --out "$work/grey" --preset fast "${ARGS[@]}" > /dev/null 2>&1
"$EV" eval "$work/colour/model.ckpt" "$work/rec" --out "$work/eval_colour" > /dev/null 2>&1
"$EV" eval "$work/grey/model.ckpt" "$work/rec" --out "$work/eval_grey" > /dev/null 2>&1
# A sigmoid radiance renders within [0, 1]: its views get the float .npy all the same (checked below).
"$EV" train "$work/rec" --out "$work/sigmoid" --preset fast-slice "${ARGS[@]}" > /dev/null 2>&1
"$EV" eval "$work/sigmoid/model.ckpt" "$work/rec" --out "$work/eval_sigmoid" > /dev/null 2>&1
"$EV" baselines "$work/rec" --out "$work/base" > /dev/null 2>&1
"$EV" train "$work/rec" --out "$work/pc" --per-channel "${ARGS[@]}" > /dev/null 2>&1
"$EV" eval "$work/pc/channels.json" "$work/rec" --out "$work/eval_pc" > /dev/null 2>&1
"$EV" render "$work/pc/channels.json" --out "$work/render_pc" --novel 1 > /dev/null 2>&1
"$EV" render "$work/pc/channels.json" --out "$work/render_sites" --novel 1 --channel-upsampling sites > /dev/null 2>&1
# Green trained on both its sites at the full sensor: the manifest says so, and eval and both upsamplings take it.
"$EV" train "$work/rec" --out "$work/pc2" --per-channel --green-sites both "${ARGS[@]}" > "$work/pc2.log" 2>&1 || fail "--green-sites both: $(tail -3 "$work/pc2.log")"
grep -q "channel G: 32x24 sensor, both green sites" "$work/pc2.log" || fail "--green-sites both: green did not train at the full sensor: $(grep channel "$work/pc2.log")"
grep -q '"green_sites": "both"' "$work/pc2/channels.json" || fail "--green-sites both: channels.json does not say so"
"$EV" eval "$work/pc2/channels.json" "$work/rec" --out "$work/eval_pc2" > /dev/null 2>&1 || fail "eval of a --green-sites both model"
"$EV" render "$work/pc2/channels.json" --out "$work/render_pc2" --novel 1 --channel-upsampling sites > /dev/null 2>&1 || fail "render --channel-upsampling sites of a --green-sites both model"
[ -f "$work/render_pc2/novel_0000.png" ] || fail "render of a --green-sites both model"
sed 's/"green_sites": "both"/"green_sites": "first"/' "$work/pc2/channels.json" > "$work/pc2/wrong.json"
if "$EV" eval "$work/pc2/wrong.json" "$work/rec" --out "$work/eval_wrong" > "$work/err" 2>&1; then fail "a green model of the full sensor was taken as a quarter-resolution one"; fi
grep -q "its camera is not the G sites of the sensor" "$work/err" || fail "wrong green_sites: $(cat "$work/err")"
if "$EV" render "$work/pc/channels.json" --out "$work/render_bad" --channel-upsampling nearest > "$work/err" 2>&1; then fail "--channel-upsampling nearest was taken"; fi
[ -f "$work/render_pc/novel_0000.png" ] && [ -f "$work/render_pc/boundary_0001_depth.npy" ] || fail "render of channels.json"
# Every view's intensity is also written as float32 .npy, whatever its range (a sigmoid radiance's too): one
# beside each intensity PNG of eval's renders and of render's views.
for d in "$work/eval_colour/renders" "$work/eval_grey/renders" "$work/eval_sigmoid/renders" "$work/render_pc"; do
  for png in "$d"/*.png; do
    case "$png" in *_depth.png) continue ;; esac
    [ -f "${png%.png}.npy" ] || fail "no ${png%.png}.npy beside $png"
  done
done
for c in r g b; do [ -f "$work/pc/$c/model.ckpt" ] || fail "per-channel: no $c/model.ckpt"; done
if "$EV" train "$work/rec" --out "$work/pc_colour" --per-channel --preset colour "${ARGS[@]}" > "$work/err" 2>&1; then fail "--per-channel took a colour variant"; fi
grep -q "renders colour; name a grey one" "$work/err" || fail "--per-channel with a colour variant: $(cat "$work/err")"
sed 's/"rggb"/"rgbg"/' "$work/pc/channels.json" > "$work/pc/bad.json"
if "$EV" eval "$work/pc/bad.json" "$work/rec" --out "$work/eval_bad" > "$work/err" 2>&1; then fail "a damaged channels.json was taken"; fi
grep -q "bad.json:0: channels.json: unknown Bayer pattern 'rgbg'" "$work/err" || fail "damaged channels.json: $(cat "$work/err")"
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
# The error split by scale (eval's error_scales): every method, in RGB and in grey; the coarse and fine MSEs
# add up to about the whole MSE, so both parts are measured against the truth as it was scored.
for m in (c, g):
    es = m["error_scales"]
    assert es["sigma_px"] == 8 and set(es["methods"]) == set(m["methods"]), es
    for name, v in es["methods"].items():
        whole = m["methods"][name]["mse"]
        assert abs(v["coarse_mse"] + v["fine_mse"] - whole) < 0.25 * whole, (name, v, whole)
    # The fine part by true depth (the simulator writes depth): three bands, cut at rising depths, whose
    # pixel shares and fine errors add up to no more than the whole.
    fd = es["fine_by_depth"]
    assert len(fd["edges_m"]) == 4 and fd["edges_m"] == sorted(fd["edges_m"]) and fd["edges_m"][0] > 0, fd
    assert 0.5 < sum(fd["pixel_share"]) <= 1 + 1e-9, fd
    assert set(fd["methods"]) == set(m["methods"]), fd
    for name, v in fd["methods"].items():
        assert len(v["fine_mse"]) == 3 and min(v["fine_mse"]) >= 0, (name, v)
        assert sum(v["fine_mse"]) <= es["methods"][name]["fine_mse"] * (1 + 1e-6) + 1e-12, (name, v, es["methods"][name])
assert png_colour_type(f"{w}/eval_grey/montage.png") == 0
b = json.load(open(f"{w}/base/baselines.json"))
assert b["channels"] == 3, "baselines on a colour recording are scored in colour"
p = json.load(open(f"{w}/eval_pc/metrics.json"))
assert p["channels"] == 3 and set(p["methods"]) == {"evnerf_fast_per_channel", "direct_integration", "high_pass_filter"}, p["methods"]
assert png_colour_type(f"{w}/eval_pc/montage.png") == 2, "the per-channel montage is in colour"
assert png_colour_type(f"{w}/render_pc/novel_0000.png") == 2, "per-channel renders are in colour"
# The two ways to the full sensor agree where the green model's sites are (both render the same ray there:
# the sites' camera is the sensor's at half the focal length) and differ between them. Depth is the green
# model's; RGGB's first green is at odd x, even y.
def npy_read(path):  # a version-1 .npy's header text and payload, without numpy
    b = open(path, "rb").read()
    n = struct.unpack("<H", b[8:10])[0]
    return b[10:10 + n].decode(), b[10 + n:]
def npy_f32(path):  # a little-endian float32 .npy of shape (24, 32)
    head, payload = npy_read(path)
    assert "'<f4'" in head and "(24, 32)" in head, (path, head)
    return struct.unpack(f"<{24 * 32}f", payload)
head, _ = npy_read(f"{w}/render_pc/novel_0000.npy")
assert "'<f4'" in head and "(24, 32, 3)" in head, ("colour views: H x W x 3", head)
import glob
sig = glob.glob(f"{w}/eval_sigmoid/renders/frame_*[0-9].npy")
assert sig, "no intensity .npy among the sigmoid model's renders"
for f in sig:
    v = npy_f32(f)
    assert 0 <= min(v) and max(v) <= 1, f"{f}: a sigmoid radiance outside [0, 1]"
for stem in ("boundary_0001", "novel_0000"):
    v = npy_f32(f"{w}/render_pc/{stem}_depth.npy")
    s = npy_f32(f"{w}/render_sites/{stem}_depth.npy")
    green = [y * 32 + x for y in range(0, 24, 2) for x in range(1, 32, 2)]
    at = max(abs(v[i] - s[i]) for i in green)
    assert at < 1e-3 * max(1.0, max(abs(a) for a in s)), f"{stem}: volume and sites differ at the green sites by {at}"
    assert max(abs(a - b) for a, b in zip(v, s)) > 10 * at + 1e-6, f"{stem}: volume rendering did not render between the sites"
for m in ("direct_integration", "high_pass_filter"):
    assert 0 < b["methods"][m]["psnr"] < 100 and 0 < c["methods"][m]["psnr"] < 100, m
PY
echo "colour: eval and baselines score a Bayer recording in RGB (grey secondary); a grey model in grey; per-channel models train, render and evaluate in colour"
