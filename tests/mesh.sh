#!/usr/bin/env bash
# A real 3-D asset end to end through the command line (ctest cli.mesh): `simulate mesh` renders a textured
# glTF file from Debian's assimp-testmodels along an orbit with held-out views off it, `train` runs a few
# steps on it before its known grey backdrop (--background 0.5, within the object's depths) and a few before
# a learned one (the default), and `eval`
# scores the training path against the baselines and the held-out views apart; a file that is no mesh is
# refused naming it, and leaves no output folder behind.
# Usage: tests/mesh.sh EVNERF_BINARY    (exit 77, skipped, without assimp-testmodels)
set -euo pipefail
EV=$1
ASSET=/usr/share/assimp/models/glTF2/BoxTextured-glTF/BoxTextured.gltf
[ -f "$ASSET" ] || { echo "SKIP: $ASSET is absent (Debian's assimp-testmodels)"; exit 77; }
work=$(mktemp -d "${TMPDIR:-/tmp}/evnerf_mesh.XXXXXX")
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
"$EV" simulate mesh "$ASSET" --out "$work/rec" --width 64 --height 48 --duration 0.5 > "$work/sim.txt" 2>&1 || fail "simulate mesh: $(cat "$work/sim.txt")"
grep -q "held-out views off the training path" "$work/sim.txt" || fail "no held-out views: $(cat "$work/sim.txt")"
grep -q "^mesh .*BoxTextured.gltf 0 0 0 1 up +y$" "$work/rec/scene.txt" || fail "scene.txt: $(cat "$work/rec/scene.txt")"
grep -q "^path orbit 0 0 0 3 30 0.5 0$" "$work/rec/scene.txt" || fail "scene.txt's path: $(cat "$work/rec/scene.txt")"
views=$(grep -vc '^#' "$work/rec/novel/poses.txt")
[ "$views" -eq 24 ] || fail "expected 24 held-out views (one revolution at 24 Hz), got $views"
[ -f "$work/rec/novel/images/view_00000023.png" ] && [ -f "$work/rec/novel/depth/view_00000023.npy" ] || fail "novel/ lacks a view's image or depth"
events=$(wc -l < "$work/rec/events.txt")
[ "$events" -gt 1000 ] || fail "only $events events from an orbit around a textured box"
"$EV" train "$work/rec" --out "$work/run" --preset fast --iterations 20 --pixels 256 --seed 1 --threads 2 --quiet --allow-collapse \
  --background 0.5 --near 1.5 --far 4.5 > "$work/train.txt" 2>&1 || fail "train: $(tail -3 "$work/train.txt")"
grep -q '"background": 0.5,' "$work/run/settings.json" || fail "settings.json does not record the background: $(cat "$work/run/settings.json")"
grep -q "backdrop luminance" "$work/train.txt" && fail "a known backdrop was learned: $(cat "$work/train.txt")"
# By default the backdrop's brightness is learned: train prints it and log.jsonl records it.
"$EV" train "$work/rec" --out "$work/learned" --iterations 50 --pixels 256 --seed 1 --threads 2 --quiet --allow-collapse \
  > "$work/learned.txt" 2>&1 || fail "train: $(tail -3 "$work/learned.txt")"
grep -q "^backdrop luminance [0-9.e+-]* (learned)$" "$work/learned.txt" || fail "train did not print the learned backdrop: $(cat "$work/learned.txt")"
grep -q '"background":\[[0-9.e+-]*\]' "$work/learned/log.jsonl" || fail "log.jsonl does not record the backdrop: $(tail -1 "$work/learned/log.jsonl")"
"$EV" train "$work/rec" --out "$work/bad" --iterations 1 --background -1 > "$work/bad.txt" 2>&1 && fail "a negative background was taken"
grep -q "background" "$work/bad.txt" || fail "the refusal of a negative background does not name it: $(cat "$work/bad.txt")"
"$EV" eval "$work/run/model.ckpt" "$work/rec" --out "$work/eval" > "$work/eval.txt" 2>&1 || fail "eval: $(tail -3 "$work/eval.txt")"
grep -q "views off the training path (24" "$work/eval.txt" || fail "eval did not score the held-out views: $(cat "$work/eval.txt")"
python3 - "$work/eval/metrics.json" <<'PY' || fail "metrics.json"
import json, sys
m = json.load(open(sys.argv[1]))
nv = m["novel_views"]
assert nv["count"] == 24, nv["count"]
ours = [k for k in nv["methods"] if k.startswith("evnerf")]
# Ours beside the flat frame: no baseline renders a new pose.
assert len(ours) == 1 and sorted(nv["methods"]) == sorted(ours + ["flat"]), list(nv["methods"])
assert 0 < nv["methods"][ours[0]]["psnr"] < 100
assert 0 < nv["methods"]["flat"]["psnr"] < 100 and nv["methods"]["flat"]["ssim"] < 1
assert "direct_integration" in m["methods"]
PY
[ -f "$work/eval/montage_novel.png" ] && [ -f "$work/eval/renders_novel/view_00000000.png" ] || fail "no renders of the held-out views"
# A file that is no mesh: refused naming it, nothing written.
printf 'not a mesh\n' > "$work/junk.gltf"
"$EV" simulate mesh "$work/junk.gltf" --out "$work/junk" > "$work/junk.txt" 2>&1 && fail "a junk file was simulated"
grep -q "junk.gltf: assimp cannot read it" "$work/junk.txt" || fail "the refusal: $(cat "$work/junk.txt")"
[ ! -e "$work/junk" ] || fail "a refused mesh left $work/junk behind"
echo "mesh: simulate mesh, train and eval with held-out views on BoxTextured.gltf; a junk file refused"
