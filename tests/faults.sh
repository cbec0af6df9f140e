#!/usr/bin/env bash
# Faults of a long training run, through the command line (ctest runs this as cli.faults):
#   1. SIGKILL in the middle of a run, then `train --resume`: the final checkpoint is byte-identical to an
#      uninterrupted run's, and the log holds each step once;
#   2. SIGINT: the run stops after the current step, writes a checkpoint, says so and exits with 130; resumed,
#      it too ends byte-identical;
#   3. an output folder that cannot be created: a clear error naming it, exit code 1, nothing written;
#   4. a resume given another --near and --far keeps the checkpoint's scene box, says so, ends
#      byte-identical, and settings.json records the box the run used.
# Usage: tests/faults.sh EVNERF_BINARY
set -euo pipefail
EV=$1
work=$(mktemp -d "${TMPDIR:-/tmp}/evnerf_faults.XXXXXX")
trap 'kill -9 $(jobs -p) 2>/dev/null || true; rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

"$EV" simulate planes --out "$work/rec" --width 64 --height 48 > /dev/null 2>&1
ARGS=(--iterations 60 --checkpoint-every 10 --pixels 1024 --seed 3 --threads 2 --quiet)
"$EV" train "$work/rec" --out "$work/whole" "${ARGS[@]}" > /dev/null 2>&1

# Waits until the checkpoint in $1 holds step ≥ $2 (read from its header: magic, version, name, parameter
# count, slices, step; written atomically, so it is always whole).
wait_for_checkpoint() {
  for _ in $(seq 1 1200); do
    python3 - "$1/model.ckpt" "$2" <<'PY' 2>/dev/null && return 0
import struct, sys
b = open(sys.argv[1], "rb").read(4096)
n = struct.unpack_from("<Q", b, 16)[0]
step = struct.unpack_from("<q", b, 24 + n + 16)[0]
sys.exit(0 if step >= int(sys.argv[2]) else 1)
PY
    sleep 0.05
  done
  fail "the run in $1 never wrote a checkpoint at step $2"
}
steps_logged() { python3 -c "import json; print(' '.join(str(json.loads(l)['step']) for l in open('$1/log.jsonl')))"; }

# 1. SIGKILL twice, resuming after each.
"$EV" train "$work/rec" --out "$work/killed" "${ARGS[@]}" > /dev/null 2>&1 &
pid=$!
wait_for_checkpoint "$work/killed" 20
kill -9 $pid
wait $pid 2>/dev/null && fail "the killed run exited normally"
"$EV" train "$work/rec" --out "$work/killed" "${ARGS[@]}" --resume > /dev/null 2>&1 &
pid=$!
wait_for_checkpoint "$work/killed" 40
kill -9 $pid
wait $pid 2>/dev/null || true
"$EV" train "$work/rec" --out "$work/killed" "${ARGS[@]}" --resume > "$work/killed.txt" 2>&1 || fail "resume after SIGKILL: $(cat "$work/killed.txt")"
cmp "$work/whole/model.ckpt" "$work/killed/model.ckpt" || fail "resumed after SIGKILL, the checkpoint differs from the uninterrupted run's"
[ "$(steps_logged "$work/killed")" = "$(steps_logged "$work/whole")" ] || fail "the resumed log's steps differ: $(steps_logged "$work/killed")"
ls "$work/killed" | grep -q '\.tmp\.' && echo "note: a killed write left a temporary file (the checkpoint itself is whole)"

# 2. SIGINT: a checkpoint, a message, exit code 130; resumed, the same end.
"$EV" train "$work/rec" --out "$work/interrupted" "${ARGS[@]}" > "$work/int.txt" 2>&1 &
pid=$!
wait_for_checkpoint "$work/interrupted" 10
kill -INT $pid
set +e
wait $pid
rc=$?
set -e
[ $rc -eq 130 ] || fail "SIGINT: exit code $rc, expected 130 ($(cat "$work/int.txt"))"
grep -q "stopped by SIGINT at step [0-9]*; the checkpoint is written, continue with --resume" "$work/int.txt" || fail "SIGINT: no message: $(cat "$work/int.txt")"
"$EV" train "$work/rec" --out "$work/interrupted" "${ARGS[@]}" --resume > /dev/null 2>&1 || fail "resume after SIGINT"
cmp "$work/whole/model.ckpt" "$work/interrupted/model.ckpt" || fail "resumed after SIGINT, the checkpoint differs"

# 3. An output folder below a regular file.
touch "$work/plain"
set +e
"$EV" train "$work/rec" --out "$work/plain/run" "${ARGS[@]}" > "$work/plain.txt" 2>&1
rc=$?
set -e
[ $rc -eq 1 ] || fail "unwritable output: exit code $rc"
grep -q "$work/plain/run:0: cannot create the output folder" "$work/plain.txt" || fail "unwritable output: $(cat "$work/plain.txt")"

# 4. Resumed with other box options: the checkpoint's box is kept and recorded.
"$EV" train "$work/rec" --out "$work/boxed" --iterations 30 --checkpoint-every 10 --pixels 1024 --seed 3 --threads 2 --quiet > /dev/null 2>&1
"$EV" train "$work/rec" --out "$work/boxed" "${ARGS[@]}" --resume --near 0.5 --far 3 > "$work/boxed.txt" 2>&1 ||
  fail "resume with other box options: $(cat "$work/boxed.txt")"
grep -q "note: the checkpoint's scene box is kept (near 0.3, far 7)" "$work/boxed.txt" || fail "resume with other box options: no note: $(cat "$work/boxed.txt")"
cmp "$work/whole/model.ckpt" "$work/boxed/model.ckpt" || fail "resumed with other box options, the checkpoint differs"
python3 - "$work/boxed/settings.json" <<'PY' || fail "resume with other box options: settings.json does not record the kept box"
import json, sys
runs = json.load(open(sys.argv[1]))["runs"]
assert [(r["from_step"], r["near"], r["far"]) for r in runs] == [(0, 0.3, 7.0), (30, 0.3, 7.0)], runs
PY
echo "faults: SIGKILL ×2 and SIGINT resumed byte-identical; unwritable output refused; a resume keeps its box"
