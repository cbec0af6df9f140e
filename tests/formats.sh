#!/usr/bin/env bash
# A recording converted to HDF5 (event_utils/HQF layout) and back reads as the same recording: `inspect`
# says the same, training on the HDF5 file gives the same parameters as on the IJRR folder, `eval` the same
# scores (frames are 8-bit in both). ctest runs this as cli.formats where evnerf is built with HDF5.
# Usage: tests/formats.sh EVNERF_BINARY
set -euo pipefail
EV=$1
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
a=$("$EV" inspect "$work/rec" | tail -n +2)
b=$("$EV" inspect "$work/h5/rec.h5" | tail -n +2)
[ "$a" = "$b" ] || fail "inspect differs: folder
$a
HDF5
$b"
ARGS=(--iters 40 --pixels 512 --seed 2 --threads 2 --quiet)
"$EV" train "$work/rec" --out "$work/run_txt" "${ARGS[@]}" > /dev/null 2>&1
"$EV" train "$work/h5/rec.h5" --out "$work/run_h5" "${ARGS[@]}" > /dev/null 2>&1
# The checkpoints differ only in the recorded source path: compare the parameters (all but the tail).
python3 - "$work/run_txt/model.ckpt" "$work/run_h5/model.ckpt" <<'PY' || fail "training on the HDF5 file gave other parameters"
import struct, sys
def params(path):  # io/checkpoint.hpp: magic, version, name, counts, step, box, density length, loss, architecture, …
    b = open(path, "rb").read()
    o = 16 + 8 + struct.unpack_from("<Q", b, 16)[0]
    count = struct.unpack_from("<Q", b, o)[0]
    o += 8 + 8 + 8 + 48 + 8
    for _ in range(2):  # loss, architecture
        o += 8 + struct.unpack_from("<Q", b, o)[0]
    return b[o:o + count * 12]  # parameters, Adam's m and v (the source path follows, in the metadata)
a, b = (params(p) for p in sys.argv[1:])
sys.exit(0 if a == b else 1)
PY
"$EV" eval "$work/run_txt/model.ckpt" "$work/rec" --out "$work/eval_txt" > /dev/null 2>&1
"$EV" eval "$work/run_h5/model.ckpt" "$work/h5/rec.h5" --out "$work/eval_h5" > /dev/null 2>&1
python3 - "$work/eval_txt/metrics.json" "$work/eval_h5/metrics.json" <<'PY' || fail "eval scores differ between the folder and the HDF5 file"
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:])
ma, mb = a["methods"], b["methods"]
sys.exit(0 if all(abs(ma[k]["psnr"] - mb[k]["psnr"]) < 1e-9 and abs(ma[k]["ssim"] - mb[k]["ssim"]) < 1e-9 for k in ma) else 1)
PY
echo "formats: IJRR → HDF5 → IJRR identical; inspect, train and eval agree on the folder and the HDF5 file"
