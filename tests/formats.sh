#!/usr/bin/env bash
# A recording converted to HDF5 (event_utils/HQF layout) and back reads as the same recording: `inspect`
# says the same, training on the HDF5 file gives the same parameters as on the IJRR folder, `eval` the same
# scores (frames are 8-bit in both); a --time-window keeps the same events from either. ctest runs this as cli.formats where evnerf is built with HDF5.
# Usage: tests/formats.sh EVNERF_BINARY
set -euo pipefail
EV=$1
HERE=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/evnerf_formats.XXXXXX")
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$EV" simulate planes --out "$work/rec" --width 48 --height 36 > /dev/null 2>&1
"$EV" convert "$work/rec" "$work/h5/rec.h5" > /dev/null
"$EV" convert "$work/h5/rec.h5" "$work/back" > /dev/null
for f in events.txt groundtruth.txt images.txt; do
  cmp "$work/rec/$f" "$work/back/$f" || fail "$f differs after IJRR → HDF5 → IJRR"
done
for i in 0 5 20; do
  cmp "$work/rec/images/frame_0000000$i.png" "$work/back/images/frame_0000000$i.png" 2>/dev/null ||
    [ ! -f "$work/rec/images/frame_0000000$i.png" ] || fail "frame $i differs after the round trip"
done
a=$("$EV" inspect "$work/rec" | tail -n +2 | grep -v "^format ")
b=$("$EV" inspect "$work/h5/rec.h5" | tail -n +2 | grep -v "^format ")
[ "$a" = "$b" ] || fail "inspect differs: folder
$a
HDF5
$b"
# --time-window: the same events from the folder and from the HDF5 file, exactly those of the window.
a=$("$EV" inspect "$work/rec" --time-window 0.5 1.25 | tail -n +2 | grep -v "^format ")
b=$("$EV" inspect "$work/h5/rec.h5" --time-window 0.5 1.25 | tail -n +2 | grep -v "^format ")
[ "$a" = "$b" ] || fail "inspect --time-window differs between the folder and the HDF5 file"
"$EV" convert "$work/h5/rec.h5" "$work/window" --time-window 0.5 1.25 > /dev/null
want=$(awk '$1 >= 0.5 && $1 < 1.25' "$work/rec/events.txt" | wc -l)
got=$(wc -l < "$work/window/events.txt")
[ "$want" -gt 0 ] && [ "$want" = "$got" ] || fail "--time-window kept $got events, the window holds $want"
ARGS=(--iterations 40 --pixels 512 --seed 2 --threads 2 --quiet)
"$EV" train "$work/rec" --out "$work/run_txt" "${ARGS[@]}" > /dev/null 2>&1
"$EV" train "$work/h5/rec.h5" --out "$work/run_h5" "${ARGS[@]}" > /dev/null 2>&1
# The checkpoints differ only in the recorded source path: compare the parameters (all but the tail).
python3 "$HERE/compare_runs.py" params "$work/run_txt/model.ckpt" "$work/run_h5/model.ckpt" || fail "training on the HDF5 file gave other parameters"
"$EV" eval "$work/run_txt/model.ckpt" "$work/rec" --out "$work/eval_txt" > /dev/null 2>&1
"$EV" eval "$work/run_h5/model.ckpt" "$work/h5/rec.h5" --out "$work/eval_h5" > /dev/null 2>&1
python3 "$HERE/compare_runs.py" metrics "$work/eval_txt/metrics.json" "$work/eval_h5/metrics.json" || fail "eval scores differ between the folder and the HDF5 file"
echo "formats: IJRR → HDF5 → IJRR identical; inspect, train and eval agree on the folder and the HDF5 file"
