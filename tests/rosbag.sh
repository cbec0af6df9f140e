#!/usr/bin/env bash
# A simulated recording written as a ROS bag by an independent writer (Debian's python3-rosbag, through
# tests/fixtures/ijrr_to_bag.py) reads as the same recording: `convert` gives back events.txt,
# groundtruth.txt and the frames byte for byte, `inspect` lists the topics, training on the bag gives the
# same parameters as on the folder, and `eval` the same scores. Bags written by evnerf (`convert x.bag`,
# each compression) read the same in python3-rosbag and back in evnerf. ctest runs this as cli.rosbag where evnerf
# is built with libbz2 and liblz4; it skips (exit 77) where python3-rosbag is not installed.
# Usage: tests/rosbag.sh EVNERF_BINARY
set -euo pipefail
EV=$1
HERE=$(cd "$(dirname "$0")" && pwd)
/usr/bin/python3 -c "import rosbag, genpy, sensor_msgs, geometry_msgs, PIL" 2>/dev/null || {
  echo "SKIP: python3-rosbag, python3-genpy, python3-sensor-msgs, python3-geometry-msgs or python3-pil missing"
  exit 77
}
work=$(mktemp -d "${TMPDIR:-/tmp}/evnerf_rosbag.XXXXXX")
trap '[ -n "${KEEP:-}" ] || rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$EV" simulate planes --out "$work/rec" --width 48 --height 36 > /dev/null 2>&1
/usr/bin/python3 "$HERE/fixtures/ijrr_to_bag.py" "$work/rec" "$work/rec.bag" lz4
"$EV" inspect "$work/rec.bag" > "$work/inspect.txt"
grep -Eq '^  /dvs/events +[0-9]+  dvs_msgs/EventArray' "$work/inspect.txt" || fail "inspect lists no /dvs/events topic: $(cat "$work/inspect.txt")"
grep -q '^time origin   1600000000 s' "$work/inspect.txt" || fail "inspect shows no time origin"
"$EV" convert "$work/rec.bag" "$work/back" > /dev/null
for f in events.txt groundtruth.txt images.txt sensor.txt; do
  cmp "$work/rec/$f" "$work/back/$f" || fail "$f differs after IJRR → bag (rosbag) → IJRR"
done
n=0
for png in "$work"/rec/images/frame_*.png; do
  cmp "$png" "$work/back/images/$(basename "$png")" || fail "$(basename "$png") differs after the round trip"
  n=$((n + 1))
done
[ "$n" -gt 5 ] || fail "only $n frames"
a=$("$EV" inspect "$work/rec" | tail -n +2 | grep -v "^format ")
b=$("$EV" inspect "$work/rec.bag" | sed -n '/^recording/,$p' | grep -v "^format " | tail -n +3)
[ "$a" = "$b" ] || fail "inspect differs: folder
$a
bag
$b"
ARGS=(--iterations 40 --pixels 512 --seed 2 --threads 2 --quiet)
"$EV" train "$work/rec" --out "$work/run_txt" "${ARGS[@]}" > /dev/null 2>&1
"$EV" train "$work/rec.bag" --out "$work/run_bag" "${ARGS[@]}" > /dev/null 2>&1
python3 "$HERE/compare_runs.py" params "$work/run_txt/model.ckpt" "$work/run_bag/model.ckpt" || fail "training on the bag gave other parameters"
"$EV" eval "$work/run_txt/model.ckpt" "$work/rec" --out "$work/eval_txt" > /dev/null 2>&1
"$EV" eval "$work/run_bag/model.ckpt" "$work/rec.bag" --out "$work/eval_bag" > /dev/null 2>&1
python3 "$HERE/compare_runs.py" metrics "$work/eval_txt/metrics.json" "$work/eval_bag/metrics.json" || fail "eval scores differ between the folder and the bag"
# evnerf's own writer: python3-rosbag reads what it writes (every compression), and it reads back the same.
for c in none bz2 lz4; do
  "$EV" convert "$work/rec" "$work/ours_$c.bag" --compression "$c" > /dev/null
  "$EV" convert "$work/ours_$c.bag" "$work/back_$c" > /dev/null
  for f in events.txt groundtruth.txt images.txt; do
    cmp "$work/rec/$f" "$work/back_$c/$f" || fail "$f differs after IJRR → bag ($c, evnerf) → IJRR"
  done
  /usr/bin/python3 - "$work/ours_$c.bag" "$work/rec/events.txt" <<'PY' || fail "python3-rosbag reads evnerf's $c bag differently"
import sys
import rosbag
bag = rosbag.Bag(sys.argv[1])
lines = [l.split() for l in open(sys.argv[2]) if l.strip()]
events = [e for topic, msg, t in bag.read_messages(topics=["/dvs/events"]) for e in msg.events]
assert len(events) == len(lines), (len(events), len(lines))
for e, l in zip(events[:: max(1, len(events) // 500)], lines[:: max(1, len(lines) // 500)]):
    whole, frac = l[0].split(".")
    assert e.ts.to_nsec() == int(whole) * 10**9 + int(frac), (e.ts.to_nsec(), l)
    assert (e.x, e.y, int(e.polarity)) == (int(l[1]), int(l[2]), int(l[3])), (e, l)
counts = {k: v.message_count for k, v in bag.get_type_and_topic_info().topics.items()}
assert counts["/dvs/camera_info"] == 1 and counts["/dvs/image_raw"] > 5 and counts["/optitrack/davis"] > 5, counts
PY
done
echo "rosbag: IJRR → bag (python3-rosbag) → IJRR identical; inspect, train and eval agree on the folder and the bag; evnerf's bags (none, bz2, lz4) read by python3-rosbag"
