#!/usr/bin/env bash
# Prophesee files: EVT 2.0 and EVT 3.0 .raw files and a .dat file, written here by an encoder of their own
# (Python, from the published word layouts: periodic time-high words, vectorised EVT 3.0 words, trigger and
# vendor words to skip, a wrap of EVT 3.0's 24-bit time), read by `convert` as exactly the events encoded;
# evnerf's own writers round-trip through both .raw versions; bad files are refused naming the byte, and one
# cut short reads to its last whole word with a warning; a header without a sensor size asks for
# --sensor-size; and, where ../shared/data has it, a real Gen3 EVT 2.0
# recording decodes to the SHA3-224 digests of an independent decoder, `inspect` describes it without a
# calibration, a --time-window keeps exactly its events, and `train` runs on it with a static pose file.
# ctest runs this as cli.prophesee. Usage: tests/prophesee.sh EVNERF_BINARY
set -euo pipefail
EV=$1
HERE=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/evnerf_prophesee.XXXXXX")
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

python3 - "$work" <<'PY'
import struct, sys
w = sys.argv[1]
W, H = 64, 48
# The events: groups of one time, row and polarity at increasing x (the order EVT 3.0 vectors give them), at
# times that rise past 2^24 µs (EVT 3.0's wrap) with gaps of up to 0.6 s.
seed = 12345
def rnd(n):
    global seed
    seed = (seed * 6364136223846793005 + 1442695040888963407) % 2**64
    return (seed >> 33) % n
events, t = [], 16_000_000
while len(events) < 4000:
    t += rnd(600_000) if rnd(50) == 0 else rnd(900)
    y, p = rnd(H), rnd(2)
    n = 1 if rnd(3) else 1 + rnd(20)
    x0 = rnd(W - n)
    xs = sorted({x0 + rnd(n) for _ in range(n)}) if n > 1 else [x0]
    events += [(t, x, y, p) for x in xs]
assert events[-1][0] > 2**24 and events[0][0] < 2**24
open(f"{w}/expected.txt", "w").write("".join(f"{t / 1e6:.9f} {x} {y} {p}\n" for t, x, y, p in events))
open(f"{w}/calib.txt", "w").write("60 60 32 24 0 0 0 0 0\n")

def groups(evs):
    out = []
    for e in evs:
        if out and out[-1][0][:1] == e[:1] and out[-1][0][2:] == e[2:] and e[1] > out[-1][-1][1]:
            out[-1].append(e)
        else:
            out.append([e])
    return out

# EVT 2.0: a time-high word for every 64 µs that passes (as a sensor sends them), CD words, now and then an
# external trigger and a vendor word.
words, high = [], None
for k, (t, x, y, p) in enumerate(events):
    while high is None or high < t >> 6:
        high = t >> 6 if high is None or (t >> 6) - high > 1000 else high + 1
        words.append(0x8 << 28 | high & 0x0FFFFFFF)
    if k % 97 == 0:
        words.append(0xA << 28 | (t & 63) << 22 | 3 << 8 | 1)
    if k % 131 == 0:
        words.append(0xE << 28 | 12345)
    words.append(p << 28 | (t & 63) << 22 | x << 11 | y)
header = f"% Date 2020-01-01 00:00:00\n% evt 2.0\n% geometry {W}x{H}\n% plugin_name test\n".encode()
open(f"{w}/fixture.evt2.raw", "wb").write(header + struct.pack(f"<{len(words)}I", *words))

# EVT 3.0: a time-high word for every 4096 µs that passes (12 bits each, wrapping), time-low words, a row
# word when the row changes, single events as EVT_ADDR_X, groups as VECT_BASE_X then alternating VECT_12 and
# VECT_8 masks; triggers and CONTINUED words between them.
words, high, low, row = [], None, None, None
for k, g in enumerate(groups(events)):
    t, _, y, p = g[0]
    while high is None or high < t >> 12:
        high = t >> 12 if high is None else high + 1
        words.append(0x8 << 12 | high & 0xFFF)
        low = None
    if low != t & 0xFFF:
        low = t & 0xFFF
        words.append(0x6 << 12 | low)
    if k % 53 == 0:
        words += [0xA << 12 | 1 << 8 | 1, 0xF << 12 | 0xABC, 0x7 << 12 | 5]
    if row != y:
        row = y
        words.append(y | (1 << 11 if k % 7 == 0 else 0))  # bit 11: the system type, not the row
    if len(g) == 1:
        words.append(0x2 << 12 | p << 11 | g[0][1])
        continue
    xs, base = [e[1] for e in g], g[0][1]
    words.append(0x3 << 12 | p << 11 | base)
    twelve = True
    while xs:
        n = 12 if twelve else 8
        mask = sum(1 << (x - base) for x in xs if x < base + n)
        words.append((0x4 if twelve else 0x5) << 12 | mask)
        xs = [x for x in xs if x >= base + n]
        base += n
        twelve = not twelve
open(f"{w}/fixture.raw", "wb").write(f"% evt 3.0\n% format EVT3;height={H};width={W}\n% end\n".encode() +
                                     struct.pack(f"<{len(words)}H", *words))

# .dat: the header, event type 0x0C and size 8, then (32-bit time, x | y << 14 | p << 28) records.
recs = b"".join(struct.pack("<II", t, x | y << 14 | p << 28) for t, x, y, p in events)
open(f"{w}/fixture.dat", "wb").write(f"% Date 2020-01-01 00:00:00\n% Version 2\n% Width {W}\n% Height {H}\n".encode() + bytes([0x0C, 8]) + recs)
PY

for f in fixture.evt2.raw fixture.raw fixture.dat; do
  "$EV" convert "$work/$f" "$work/out_${f//./_}" > "$work/convert.log" 2>&1 || fail "convert $f: $(cat "$work/convert.log")"
  cmp "$work/expected.txt" "$work/out_${f//./_}/events.txt" || fail "$f: the events read are not the events encoded"
done
"$EV" inspect "$work/fixture.raw" > "$work/inspect.txt" 2>&1 || fail "inspect: $(cat "$work/inspect.txt")"
grep -q "^format        evt3" "$work/inspect.txt" || fail "inspect does not name the format: $(cat "$work/inspect.txt")"
grep -q "evt 3.0, 64x48 (from the header's format line)" "$work/inspect.txt" || fail "inspect does not describe the header: $(cat "$work/inspect.txt")"
grep -q "other words" "$work/inspect.txt" || fail "inspect does not count the skipped words"

# evnerf's writers: EVT 3.0 for .raw, EVT 2.0 for .evt2.raw; each reads back as the same events.
"$EV" convert "$work/out_fixture_raw" "$work/mine/ours.raw" > /dev/null
"$EV" convert "$work/out_fixture_raw" "$work/mine2/ours.evt2.raw" > /dev/null
head -c 9 "$work/mine/ours.raw" | grep -q "% evt 3.0" || fail ".raw is not written as EVT 3.0"
head -c 9 "$work/mine2/ours.evt2.raw" | grep -q "% evt 2.0" || fail ".evt2.raw is not written as EVT 2.0"
for f in mine/ours.raw mine2/ours.evt2.raw; do
  "$EV" convert "$work/$f" "$work/back_${f%%/*}" > /dev/null
  cmp "$work/expected.txt" "$work/back_${f%%/*}/events.txt" || fail "$f: evnerf's writer and reader disagree"
done

# A bare camera file (no calib.txt beside it): its events convert, and no calibration is made up for it.
mkdir -p "$work/bare"
cp "$work/fixture.raw" "$work/bare/"
"$EV" convert "$work/bare/fixture.raw" "$work/bare_out" > "$work/bare.log" 2>&1 || fail "convert of a bare file: $(cat "$work/bare.log")"
grep -q "has no calibration" "$work/bare.log" || fail "convert does not say the calibration is missing: $(cat "$work/bare.log")"
cmp "$work/expected.txt" "$work/bare_out/events.txt" || fail "bare file: the events read are not the events encoded"
[ ! -e "$work/bare_out/calib.txt" ] || fail "convert wrote a calibration it was not given"
"$EV" convert "$work/bare/fixture.raw" "$work/bare_h5/ours.raw" > /dev/null 2>&1 || fail "convert of a bare file to .raw"
[ ! -e "$work/bare_h5/calib.txt" ] || fail "convert wrote a calibration beside a file it was not given"
"$EV" inspect "$work/bare_out" > "$work/bare_inspect.txt" 2>&1 || fail "inspect of the converted folder: $(cat "$work/bare_inspect.txt")"
grep -q "no calibration" "$work/bare_inspect.txt" || fail "inspect of the converted folder does not warn: $(cat "$work/bare_inspect.txt")"
grep -q "pixel intervals" "$work/bare_inspect.txt" || fail "inspect does not report the pixel intervals: $(cat "$work/bare_inspect.txt")"

# Bad files: the error names the file and the byte, and what was wrong.
refused() {  # file expected-message [flags…]
  local f=$1 want=$2
  shift 2
  if "$EV" inspect "$f" "$@" > "$work/err" 2>&1; then fail "$f was read"; fi
  grep -qF -- "$want" "$work/err" || fail "$f: expected '$want', got: $(cat "$work/err")"
}
cp "$work/fixture.evt2.raw" "$work/bad/" 2>/dev/null || mkdir -p "$work/bad"
cp "$work/calib.txt" "$work/bad/"
python3 - "$work" <<'PY'
import struct, sys
w = sys.argv[1]
good = open(f"{w}/fixture.evt2.raw", "rb").read()
n = good.index(b"% plugin_name test\n") + len(b"% plugin_name test\n")
open(f"{w}/bad/truncated.raw", "wb").write(good[:-2])
open(f"{w}/bad/truncated.offset", "w").write(str(n + (len(good) - 2 - n) // 4 * 4))  # the cut word's byte
h = b"% evt 2.0\n% geometry 64x48\n"
cd = lambda t, x, y: struct.pack("<I", 1 << 28 | (t & 63) << 22 | x << 11 | y)
high = lambda t: struct.pack("<I", 8 << 28 | t >> 6)
open(f"{w}/bad/backwards.raw", "wb").write(h + high(6400) + cd(6410, 1, 1) + cd(6405, 2, 2))
open(f"{w}/bad/high_backwards.raw", "wb").write(h + high(6400) + cd(6400, 1, 1) + high(6336) + cd(6336, 1, 1))
open(f"{w}/bad/outside.raw", "wb").write(h + high(64) + cd(64, 70, 1))
open(f"{w}/bad/version.raw", "wb").write(b"% evt 4.0\n% geometry 64x48\n" + high(64))
open(f"{w}/bad/nosize.raw", "wb").write(b"% evt 2.0\n" + high(64) + cd(64, 3, 4))
PY
# A file cut short inside its last word reads to the word before, with one warning.
off=$(cat "$work/bad/truncated.offset")
"$EV" inspect "$work/bad/truncated.raw" > "$work/cut.txt" 2>&1 || fail "a file cut short was refused: $(cat "$work/cut.txt")"
grep -qF "truncated.raw: byte $off: the file ends 2 bytes into a 4-byte word (a recording cut short); read to the last whole word, 2 bytes dropped" "$work/cut.txt" ||
  fail "no warning naming where the file was cut: $(cat "$work/cut.txt")"
refused "$work/bad/backwards.raw" "backwards.raw:0: byte 35: time runs backwards (6405 µs after 6410 µs)"
refused "$work/bad/high_backwards.raw" "high_backwards.raw:0: byte 35: EVT_TIME_HIGH runs backwards"
refused "$work/bad/outside.raw" "outside.raw:0: byte 31: event at x 70, y 1 outside the 64x48 sensor"
refused "$work/bad/version.raw" "Prophesee evt 4.0: evnerf reads EVT 2.0 and EVT 3.0 .raw files"
refused "$work/bad/nosize.raw" "give it with --sensor-size WxH"
"$EV" inspect "$work/bad/nosize.raw" --sensor-size 64x48 > "$work/ok.txt" 2>&1 || fail "--sensor-size: $(cat "$work/ok.txt")"
grep -q "64x48 (from --sensor-size)" "$work/ok.txt" || fail "--sensor-size was not used: $(cat "$work/ok.txt")"
refused "$work/bad/nosize.raw" "--sensor-size: expected WxH" --sensor-size 64

# The real recording (Gen3, EVT 2.0, 640x480, 521,252 events), when ../shared/data has it.
real=$HERE/../../shared/data/prophesee_evt2_sample/evt2.raw
if [ ! -f "$real" ]; then
  echo "prophesee: fixtures read as encoded; $real absent, the real recording's checks skipped"
  exit 0
fi
"$EV" inspect "$real" > "$work/real.txt" 2>&1 || fail "inspect of the real recording: $(cat "$work/real.txt")"
grep -q "evt 2.0, 640x480 (from the sensor generation of the header's plugin_name)" "$work/real.txt" || fail "real: $(cat "$work/real.txt")"
grep -q "no calibration: training needs calib.txt beside the file or --calib" "$work/real.txt" || fail "real: no warning of the missing calibration"
echo "500 500 320 240 0 0 0 0 0" > "$work/real_calib.txt"
"$EV" convert "$real" "$work/real" --calib "$work/real_calib.txt" > /dev/null
"$EV" inspect "$real" --calib "$work/real_calib.txt" --time-window 913.75 913.76 > "$work/window.txt" 2>&1
python3 - "$work" <<'PY' || fail "the real recording's digests"
import hashlib, struct, sys
w = sys.argv[1]
t, x, y, on = [], [], [], []
for line in open(f"{w}/real/events.txt"):
    a, b, c, d = line.split()
    t.append(round(float(a) * 1e6)), x.append(int(b)), y.append(int(c)), on.append(int(d))
n = len(t)
assert n == 521252, n
digest = lambda fmt, v: hashlib.sha3_224(struct.pack(f"<{n}{fmt}", *v)).hexdigest()
want = {"t": "9855ba39c1baea316ae623b72466e420df60a7510248391856eb4eaf", "x": "93fc6cff19b483fd48ca53345c6c1cf05123681d7b7272a1717e9303",
        "y": "07cfaef58e5fa71ce9910ed5b88fb7e9fcf71e4a8654cc2c4666f1ae", "on": "d2b5e9c4047f4c431937b24cd46c8b504e055372b0ded1df77f0ffa1"}
got = {"t": digest("Q", t), "x": digest("H", x), "y": digest("H", y), "on": digest("B", on)}
assert got == want, got
inside = sum(913_750_000 <= v < 913_760_000 for v in t)
text = open(f"{w}/window.txt").read()
assert f"events        {inside} (" in text, (inside, text)
PY
# Training runs on it with a pose file of a camera that does not move (there is no ground truth to score).
printf '913.70 0 0 0 0 0 0 1\n913.82 0 0 0 0 0 0 1\n' > "$work/static.txt"
"$EV" train "$real" --calib "$work/real_calib.txt" --poses "$work/static.txt" --out "$work/run" --iterations 10 --pixels 256 \
  --threads 2 --quiet --allow-collapse > "$work/train.txt" 2>&1 || fail "train on the real recording: $(tail -3 "$work/train.txt")"
grep -q "trained fast: 10 steps" "$work/train.txt" || fail "train did not report: $(cat "$work/train.txt")"
echo "prophesee: EVT 2.0, EVT 3.0 and .dat fixtures read as encoded, both writers round-trip, bad files refused by byte; the real EVT 2.0 recording gives the four digests and trains"
