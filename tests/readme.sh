#!/usr/bin/env bash
# The README's "Your own recording" block runs as written on a small simulated recording, as an IJRR folder,
# as an HDF5 file (where evnerf has HDF5) and as a ROS bag (where it has bags): the block's lines are taken
# from README.md itself, `B` pointed at the binary under test and `rec/` at the fixture; the one change is
# a short training (--iterations 30 --pixels 256 appended to `train`), so the test takes seconds, not minutes.
# ctest runs this as docs.readme. Usage: tests/readme.sh EVNERF_BINARY
set -euo pipefail
EV=$(realpath "$1")
HERE=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/evnerf_readme.XXXXXX")
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
block=$(awk '/^## Your own recording/ {on = 1} on && /^```sh/ {take = 1; next} take && /^```/ {exit} take {print}' "$HERE/../README.md")
[ -n "$block" ] || fail "README.md has no sh block under '## Your own recording'"
grep -q '^B=' <<<"$block" && grep -q '\$B train rec/' <<<"$block" || fail "the block no longer sets B and trains on rec/: update this test with it"
"$EV" simulate object --out "$work/fixture" --width 48 --height 36 > /dev/null 2>&1
kinds=(folder)
"$EV" convert "$work/fixture" "$work/h5/rec.h5" > /dev/null 2>&1 && kinds+=(h5)
"$EV" convert "$work/fixture" "$work/bag/rec.bag" > /dev/null 2>&1 && kinds+=(bag)
for kind in "${kinds[@]}"; do
  dir="$work/$kind"
  mkdir -p "$dir"
  case $kind in
    folder) cp -r "$work/fixture" "$dir/rec"; target=rec/ ;;
    h5) target=rec.h5 ;;
    bag) target=rec.bag ;;
  esac
  script=$(sed -e "s|^B=.*|B=$EV|" -e "s|\(\$B train rec/.*\)#|\1 --iterations 30 --pixels 256 #|" -e "s|rec/|$target|g" <<<"$block")
  (cd "$dir" && bash -euo pipefail -c "$script") > "$dir/log.txt" 2>&1 || fail "$kind: the README's block failed: $(tail -5 "$dir/log.txt")"
  [ -f "$dir/run/model.ckpt" ] && [ -f "$dir/run/eval/metrics.json" ] && [ -f "$dir/run/eval/montage.png" ] &&
    ls "$dir/run/render/"novel_*.png > /dev/null 2>&1 || fail "$kind: the block's outputs are missing"
  [ -f "$dir/run/export/transforms.json" ] && [ -f "$dir/run/export/points.ply" ] || fail "$kind: export wrote no cameras or points"
  # The block's field trains a few steps: too few to be opaque anywhere, so the Gaussians say they start in the
  # frusta (test_splat_model.cpp starts them from a teacher's surfaces).
  [ -f "$dir/gs/model.ckpt" ] && grep -q "^started [0-9]* Gaussians from the surfaces of\|the Gaussians start in the cameras' frusta, taught by it" "$dir/log.txt" ||
    fail "$kind: the Gaussians did not take the field as their teacher"
  grep -q "^format " "$dir/log.txt" || fail "$kind: inspect printed no format"
done
echo "readme: the own-recording block runs as written on ${kinds[*]}"
