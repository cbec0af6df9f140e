#!/usr/bin/env bash
# Data-parallel training under mpirun (ctest runs this as mpi.train when built with EVNERF_MPI=ON):
#   1. `mpirun -np 2 evnerf train` (fast, and splat) ends bit-identical to one process with `--shards 2`, and to itself run
#      again; sparse and dense gradient exchange give the same model;
#   2. a run stopped at step 15 and resumed under mpirun ends bit-identical to the whole run; a checkpoint
#      of 2 shards resumed with 1 is refused with a clear error; 2 processes with 4 shards train;
#   3. a process killed mid-run ends the job promptly (no hang) and leaves the last checkpoint whole;
#      an error on rank 0 alone (its output folder cannot be created) ends every process with its message;
#      the verbs other than train refuse to run in several processes.
# Usage: tests/mpi.sh EVNERF_BINARY   (exit 77: skipped, no mpirun)
set -euo pipefail
EV=$(realpath "$1")
command -v mpirun >/dev/null || { echo "mpirun not found: skipped"; exit 77; }
work=$(mktemp -d "${TMPDIR:-/tmp}/evnerf_mpi.XXXXXX")
trap 'kill -9 $(jobs -p) 2>/dev/null || true; rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
# Root in a container: OpenMPI refuses root unless told; no shared-memory single-copy (needs ptrace rights).
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl_vader_single_copy_mechanism=none
MPIRUN=(mpirun --oversubscribe --bind-to none)

"$EV" simulate planes --out "$work/rec" --width 48 --height 36 >/dev/null 2>&1
ARGS=(--iterations 30 --checkpoint-every 10 --pixels 512 --seed 5 --threads 1 --quiet)
run2() { timeout 300 "${MPIRUN[@]}" -np 2 "$EV" train "$work/rec" "$@"; }

# 1. Two processes equal one process with two shards, bit for bit; reruns and exchanges agree.
"$EV" train "$work/rec" --out "$work/one" --shards 2 "${ARGS[@]}" >"$work/one.txt" 2>&1 || { cat "$work/one.txt"; fail "one process, 2 shards"; }
run2 --out "$work/two" "${ARGS[@]}" >"$work/two.txt" 2>&1 || { cat "$work/two.txt"; fail "mpirun -np 2"; }
cmp -s "$work/one/model.ckpt" "$work/two/model.ckpt" || fail "mpirun -np 2 differs from one process with --shards 2"
grep -q "in each of 2 processes, 2 shards per step" "$work/two.txt" || { cat "$work/two.txt"; fail "no process count in the start line"; }
[ "$(grep -c '^trained' "$work/two.txt")" = 1 ] || { cat "$work/two.txt"; fail "not exactly one process reported"; }
python3 - "$work/two/log.jsonl" "$work/one/log.jsonl" <<'PY' || fail "the log lacks the exchange's figures"
import json, sys
two = [json.loads(l) for l in open(sys.argv[1])]
one = [json.loads(l) for l in open(sys.argv[2])]
assert two and all(r["shards"] == 2 and r["ranks"] == 2 and r["exchange_bytes_per_step"] > 0 for r in two), two[-1]
assert all("ranks" not in r for r in one)
assert [r["loss"] for r in one] == [r["loss"] for r in two], "the logged losses differ"
PY
run2 --out "$work/again" "${ARGS[@]}" >/dev/null 2>&1 || fail "mpirun -np 2, again"
cmp -s "$work/two/model.ckpt" "$work/again/model.ckpt" || fail "two mpirun runs of one seed differ"
for ex in dense sparse; do
  run2 --out "$work/$ex" --exchange $ex "${ARGS[@]}" >/dev/null 2>&1 || fail "--exchange $ex"
  cmp -s "$work/two/model.ckpt" "$work/$ex/model.ckpt" || fail "--exchange $ex differs from auto"
done

# Gaussians (the splat preset) train data-parallel by the same step: two processes equal two shards.
"$EV" train "$work/rec" --preset splat --out "$work/s_one" --shards 2 "${ARGS[@]}" >"$work/s_one.txt" 2>&1 || { cat "$work/s_one.txt"; fail "splat, one process, 2 shards"; }
run2 --preset splat --out "$work/s_two" "${ARGS[@]}" >"$work/s_two.txt" 2>&1 || { cat "$work/s_two.txt"; fail "splat, mpirun -np 2"; }
cmp -s "$work/s_one/model.ckpt" "$work/s_two/model.ckpt" || fail "splat: mpirun -np 2 differs from one process with --shards 2"

# 2. Resume under mpirun: 15 steps, then on to 30, equals the whole run.
SHORT=(--iterations 15 --checkpoint-every 10 --pixels 512 --seed 5 --threads 1 --quiet)
run2 --out "$work/res" "${SHORT[@]}" >/dev/null 2>&1 || fail "the first half"
run2 --out "$work/res" --resume "${ARGS[@]}" >"$work/res.txt" 2>&1 || { cat "$work/res.txt"; fail "the resumed half"; }
grep -q "resuming fast at step 15" "$work/res.txt" || { cat "$work/res.txt"; fail "no resume line"; }
cmp -s "$work/two/model.ckpt" "$work/res/model.ckpt" || fail "resumed under mpirun differs from the whole run"
# The same checkpoint resumed by one process with its 2 shards goes on; with 1 shard it is refused.
"$EV" train "$work/rec" --out "$work/res" --resume --shards 2 --iterations 32 --pixels 512 --seed 5 --threads 1 --quiet >/dev/null 2>&1 ||
  fail "one process could not resume a 2-process checkpoint with --shards 2"
if "$EV" train "$work/rec" --out "$work/res" --resume --iterations 40 --quiet >"$work/refused.txt" 2>&1; then fail "a 2-shard checkpoint resumed with 1 shard"; fi
grep -q "trained with 2 shard(s) per step, this run has 1 (processes × shards): resume with --shards 2" "$work/refused.txt" ||
  { cat "$work/refused.txt"; fail "no clear error for a shard mismatch"; }
# 2 processes, 4 shards each step (2 each): trains, logs 4 shards.
run2 --out "$work/four" --shards 4 "${SHORT[@]}" >"$work/four.txt" 2>&1 || { cat "$work/four.txt"; fail "-np 2 --shards 4"; }
grep -q '"shards":4' "$work/four/log.jsonl" || fail "the 4-shard run does not log 4 shards"
if run2 --out "$work/three" --shards 3 "${SHORT[@]}" >"$work/three.txt" 2>&1; then fail "3 shards on 2 processes accepted"; fi
grep -q "must be a multiple of the processes (2)" "$work/three.txt" || { cat "$work/three.txt"; fail "3 shards on 2 processes: no clear error"; }

# 3. A killed process ends the job, not a hang; the checkpoint stays whole.
timeout 300 "${MPIRUN[@]}" -np 2 "$EV" train "$work/rec" --out "$work/dead" --iterations 100000 --checkpoint-every 10 --pixels 512 --seed 5 \
  --threads 1 --quiet >"$work/dead.txt" 2>&1 &
job=$!
for _ in $(seq 1 1200); do [ -f "$work/dead/model.ckpt" ] && break; sleep 0.05; done
[ -f "$work/dead/model.ckpt" ] || fail "the long run never wrote a checkpoint"
victim=$(pgrep -f -- "--out $work/dead" | while read -r p; do [ "$(cat /proc/$p/comm 2>/dev/null)" = evnerf ] && echo "$p"; done | tail -1)
[ -n "$victim" ] || fail "no evnerf process of the long run found"
kill -9 "$victim"
start=$SECONDS
code=0
wait $job || code=$?
[ $code != 0 ] || fail "the job survived a killed process"
[ $code != 124 ] || fail "the job hung after a process was killed"
[ $((SECONDS - start)) -lt 60 ] || fail "the job took $((SECONDS - start)) s to end after a process was killed"
grep -q "exited on signal 9" "$work/dead.txt" || { cat "$work/dead.txt"; fail "mpirun did not say which process died"; }
"$EV" train "$work/rec" --out "$work/dead" --resume --shards 2 --iterations 1 --quiet >"$work/dead_resume.txt" 2>&1 ||
  { cat "$work/dead_resume.txt"; fail "the checkpoint left by the killed job does not load"; }
# SIGTERM to mpirun (a batch system's stop) reaches every process: all stop at one step, rank 0 writes it.
timeout 300 "${MPIRUN[@]}" -np 2 "$EV" train "$work/rec" --out "$work/term" --iterations 100000 --checkpoint-every 10 --pixels 512 --seed 5 \
  --threads 1 --quiet >"$work/term.txt" 2>&1 &
job=$!
for _ in $(seq 1 1200); do [ -f "$work/term/model.ckpt" ] && break; sleep 0.05; done
[ -f "$work/term/model.ckpt" ] || fail "the run to stop never wrote a checkpoint"
pkill -TERM -P "$job" -x mpirun
wait $job || true
stopped=$(sed -n 's/^train: stopped by SIGTERM at step \([0-9]*\);.*/\1/p' "$work/term.txt")
[ -n "$stopped" ] || { cat "$work/term.txt"; fail "SIGTERM: no stop message"; }
"$EV" train "$work/rec" --out "$work/term" --resume --shards 2 --iterations 1 --quiet >"$work/term_resume.txt" 2>&1 ||
  { cat "$work/term_resume.txt"; fail "the stopped run's checkpoint does not load"; }
grep -q "resuming fast at step $stopped\$" "$work/term_resume.txt" || { cat "$work/term_resume.txt"; fail "the checkpoint is not of step $stopped"; }
# Rank 0 alone fails (its output folder lies under a file); every process ends with the message.
: >"$work/plainfile"
if run2 --out "$work/plainfile/run" "${SHORT[@]}" >"$work/err.txt" 2>&1; then fail "an impossible output folder was accepted"; fi
grep -q "evnerf train: error (rank 0 of 2): .*plainfile/run:0: cannot create the output folder" "$work/err.txt" ||
  { cat "$work/err.txt"; fail "no clear error from rank 0"; }
# Only train runs in several processes.
if timeout 120 "${MPIRUN[@]}" -np 2 "$EV" inspect "$work/rec" >"$work/inspect.txt" 2>&1; then fail "inspect ran in 2 processes"; fi
grep -q "only train runs in several processes" "$work/inspect.txt" || { cat "$work/inspect.txt"; fail "inspect: no clear error"; }
echo "mpi: 2 processes = 1 process with 2 shards (bit for bit, dense = sparse), resume exact, shard mismatch refused, dead process and rank-0 error end the job"
