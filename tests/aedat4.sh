#!/usr/bin/env bash
# AEDAT4 files written by an independent writer (tests/aedat4_fixture.py: Debian's python3-flatbuffers,
# python3-lz4, python3-zstandard, from the published schemas), with Unix-time stamps, interleaved frame, IMU
# and trigger streams, a region-of-interest frame and a BGR frame, without a data table (LZ4) and with one
# (Zstd, none): `convert` reads exactly the events and frames written, on the clock of the whole second of the
# first event, with the pose file beside it read in the file's clock; a time window read through the data
# table keeps exactly its events; `inspect` describes a file without a calibration; evnerf's writer
# round-trips (and the independent reader reads it back); a file cut short reads to its last whole packet;
# bad files are refused naming the byte or packet.
# ctest runs this as cli.aedat4. Usage: tests/aedat4.sh EVNERF_BINARY
set -euo pipefail
EV=$1
HERE=$(cd "$(dirname "$0")" && pwd)
PY=/usr/bin/python3  # Debian's interpreter, whose flatbuffers, lz4 and zstandard modules the fixture uses
work=$(mktemp -d "${TMPDIR:-/tmp}/evnerf_aedat4.XXXXXX")
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$PY" "$HERE/aedat4_fixture.py" write "$work"
times_of() { awk '{print $1}' "$1"; }

# The three files decode to exactly the events and full-sensor frames written.
for c in lz4 zstd none; do
  "$EV" convert "$work/$c.aedat4" "$work/out_$c" > "$work/convert_$c.log"
  cmp -s "$work/expected.txt" "$work/out_$c/events.txt" || { diff "$work/expected.txt" "$work/out_$c/events.txt" | head; fail "$c: events differ"; }
  times_of "$work/out_$c/images.txt" > "$work/frames_$c.txt"
  cmp -s "$work/expected_frames.txt" "$work/frames_$c.txt" || fail "$c: frame times differ"
  # The poses beside the file, in Unix seconds, arrive on the recording's clock: the first at 0.
  head -1 "$work/out_$c/groundtruth.txt" | grep -q '^0.000000000 ' || fail "$c: poses not moved to the recording's clock: $(head -1 "$work/out_$c/groundtruth.txt")"
done
# The grey frame's pixels and the BGR frame as RGB (fixture: grey (3x + 5y + k) mod 256; BGR (10, 20 + x, 30 + y)).
"$PY" - "$work" <<'PY'
import sys
from PIL import Image
w = sys.argv[1]
names = [l.split()[1] for l in open(f"{w}/out_zstd/images.txt")]
g = Image.open(f"{w}/out_zstd/{names[0]}").convert("L")
assert g.size == (64, 48), g.size
for x, y in ((0, 0), (5, 7), (63, 47)):
    assert g.getpixel((x, y)) == (3 * x + 5 * y) % 256, (x, y, g.getpixel((x, y)))
rgb = Image.open(f"{w}/out_zstd/{names[3]}").convert("RGB")
for x, y in ((0, 0), (9, 4)):
    assert rgb.getpixel((x, y)) == (30 + y, 20 + x, 10), (x, y, rgb.getpixel((x, y)))
PY

# inspect: format, streams, the data table, the clock; without a calibration beside the file, a warning only.
mkdir "$work/bare" && cp "$work/zstd.aedat4" "$work/bare/"
"$EV" inspect "$work/bare/zstd.aedat4" > "$work/inspect.txt" 2>&1 || { cat "$work/inspect.txt"; fail "inspect refused a file without calib.txt"; }
for want in "format        aedat4" "Zstd compression" "0 EVTS (events), 1 FRME (frames), 2 IMUS (imu), 3 TRIG (triggers)" \
            "data table read" "time origin   1700000123 s" "1 not of the whole sensor"; do
  grep -qF "$want" "$work/inspect.txt" || { cat "$work/inspect.txt"; fail "inspect does not say '$want'"; }
done
"$EV" inspect "$work/lz4.aedat4" > "$work/inspect_lz4.txt"
grep -q "no data table" "$work/inspect_lz4.txt" || fail "inspect of the LZ4 file does not say it has no data table"

# A time window through the data table: exactly the events of [2, 5) s.
"$EV" convert "$work/zstd.aedat4" "$work/win" --time-window 2 5 > /dev/null
awk '$1 >= 2 && $1 < 5' "$work/expected.txt" > "$work/expected_win.txt"
[ -s "$work/expected_win.txt" ] || fail "the window holds no events (fixture changed?)"
cmp -s "$work/expected_win.txt" "$work/win/events.txt" || fail "the time window's events differ"
"$EV" inspect "$work/zstd.aedat4" --time-window 2 5 > "$work/inspect_win.txt"
grep -qE "packets read, [1-9][0-9]* skipped" "$work/inspect_win.txt" || fail "inspect with a window does not report skipped packets"

# evnerf's writer: an IJRR folder to AEDAT4 (LZ4 and Zstd) and back, the same events; the independent reader
# (python3-flatbuffers) reads the same events from it.
for c in lz4 zstd; do
  mkdir -p "$work/rt_$c"
  "$EV" convert "$work/out_zstd" "$work/rt_$c/rec.aedat4" --compression "$c" > /dev/null
  "$EV" convert "$work/rt_$c/rec.aedat4" "$work/back_$c" > /dev/null
  cmp -s "$work/expected.txt" "$work/back_$c/events.txt" || fail "$c: evnerf's AEDAT4 writer does not round-trip"
  [ "$(wc -l < "$work/back_$c/images.txt")" = "$(wc -l < "$work/out_zstd/images.txt")" ] || fail "$c: frames lost in the round trip"
  "$PY" "$HERE/aedat4_fixture.py" read "$work/rt_$c/rec.aedat4" "$work/py_$c.txt"
  awk '{printf "%.9f %d %d %d\n", $1 / 1e6, $2, $3, $4}' "$work/py_$c.txt" > "$work/py_$c.events"
  cmp -s "$work/expected.txt" "$work/py_$c.events" || { diff "$work/expected.txt" "$work/py_$c.events" | head -4; fail "$c: the independent reader reads other events"; }
done
"$EV" convert "$work/out_zstd" "$work/rt_bad.aedat4" --compression bz2 > "$work/bz2.txt" 2>&1 && fail "bz2 accepted for AEDAT4"
grep -q "AEDAT4 compression 'bz2' (known: none, lz4, zstd)" "$work/bz2.txt" || { cat "$work/bz2.txt"; fail "bz2's error"; }

# Bad files: each refused with what is wrong and where.
expect_error() {  # FILE PATTERN [ARGS...]
  local f=$1 pat=$2
  shift 2
  if "$EV" convert "$f" "$work/bad_out" "$@" > "$work/err.txt" 2>&1; then fail "$f was accepted"; fi
  grep -qE "$pat" "$work/err.txt" || { cat "$work/err.txt"; fail "$f: expected /$pat/"; }
  [ ! -e "$work/bad_out/events.txt" ] || fail "$f: output written for a refused file"
}
expect_error "$work/backwards.aedat4" "backwards.aedat4: byte [0-9]+ \(packet of stream 0\): event 1: time runs backwards"
expect_error "$work/outside.aedat4" "event 1 at x 64, y 2 outside the 64x48 sensor"
expect_error "$work/nosize.aedat4" "gives no sensor size \(sizeX, sizeY\): give it with --sensor-size WxH"
"$EV" convert "$work/nosize.aedat4" "$work/nosize_out" --sensor-size 64x48 > /dev/null || fail "--sensor-size did not rescue a file without sizeX/sizeY"
at=$(cat "$work/corrupt_at.txt")
expect_error "$work/corrupt.aedat4" "byte $at \(packet of stream 0\): (corrupt LZ4 frame|the LZ4 frame ends early)"
# A recording cut short (the LZ4 file has no data table, as a recorder that stopped leaves it) reads to its
# last whole packet, with one warning naming the byte: its events are the whole file's first ones.
head -c $(($(stat -c %s "$work/lz4.aedat4") * 2 / 3)) "$work/lz4.aedat4" > "$work/cut.aedat4"
"$EV" convert "$work/cut.aedat4" "$work/cut_out" > "$work/cut.log" 2>&1 || { cat "$work/cut.log"; fail "a file cut short was refused"; }
grep -qE "cut.aedat4: byte [0-9]+: (packet of [0-9]+ bytes runs past the end of the file|the file ends inside a packet header) \(a recording cut short\); read to the last whole packet, [0-9]+ bytes dropped" "$work/cut.log" ||
  { cat "$work/cut.log"; fail "no warning naming where the file was cut"; }
[ "$(grep -c "cut short" "$work/cut.log")" = 1 ] || { cat "$work/cut.log"; fail "more than one warning for one cut"; }
n=$(wc -l < "$work/cut_out/events.txt")
[ "$n" -gt 0 ] && [ "$n" -lt "$(wc -l < "$work/expected.txt")" ] || fail "a cut file read $n events"
head -n "$n" "$work/expected.txt" | cmp -s - "$work/cut_out/events.txt" || fail "a cut file's events are not the whole file's first ones"
printf '#!AER-DAT4.0\r\n\x10\x00\x00\x00abc' > "$work/header.aedat4"
expect_error "$work/header.aedat4" "the IOHeader of 16 bytes runs past the end of the file"
printf '#!AER-DAT3.1\r\n' > "$work/v3.aedat4"
expect_error "$work/v3.aedat4" "not a recording evnerf reads"
echo "aedat4: ok"
