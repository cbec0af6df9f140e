#!/usr/bin/env bash
# The parts under examples/parts/ end to end through cli::main (custom_parts): a recording simulated, the
# EventNeRF objective and the quiet-pixels regulariser each trained, rendered and evaluated; the log names the
# regulariser's term, and a variant's checkpoint is refused by the other's loss; eval's output is one table
# unless --verbose; a file format registered by the program (CSV) is written, read and trained on.
# Usage: tests/parts.sh path/to/custom_parts
set -euo pipefail
EV=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$EV" simulate planes --out "$work/rec" --width 48 --height 36 > /dev/null 2>&1
ARGS=(--iterations 60 --pixels 256 --seed 1 --threads 2 --quiet --allow-collapse --checkpoint-every 0)
for v in fast-eventnerf fast-quiet; do
  "$EV" train "$work/rec" --out "$work/$v" --variant "$v" "${ARGS[@]}" > "$work/$v.txt" 2>&1
  "$EV" render "$work/$v/model.ckpt" --out "$work/$v/render" --novel 1 > /dev/null
  "$EV" eval "$work/$v/model.ckpt" "$work/rec" --out "$work/$v/eval" > "$work/$v.eval.txt"
  test -s "$work/$v/eval/metrics.json" || { echo "no metrics for $v"; exit 1; }
  grep -q '"variant": "'"$v"'"' "$work/$v/settings.json" || { echo "settings.json does not name $v"; exit 1; }
done
# eval prints one table (the default alignment: ours and both baselines); --verbose prints the rest, and a
# depth band whose edges meet (planes' back plane) reads "at z m", never "z-z m".
[ "$(grep -c '^method ' "$work/fast-quiet.eval.txt")" = 1 ] || { cat "$work/fast-quiet.eval.txt"; echo "eval printed more than one table"; exit 1; }
grep -q "coarse PSNR" "$work/fast-quiet.eval.txt" && { echo "eval printed the error by scale without --verbose"; exit 1; }
"$EV" eval "$work/fast-quiet/model.ckpt" "$work/rec" --out "$work/eval_verbose" --verbose > "$work/verbose.txt"
for want in "coarse PSNR" "alignment: min-max" "by true depth"; do
  grep -q "$want" "$work/verbose.txt" || { cat "$work/verbose.txt"; echo "eval --verbose lacks '$want'"; exit 1; }
done
if grep -Eq '([0-9]+\.[0-9]+)-\1 m' "$work/verbose.txt"; then cat "$work/verbose.txt"; echo "a degenerate depth band"; exit 1; fi
# The event loss falls over the run (the objective learns); the regulariser's term is logged under its name.
python3 - "$work" <<'PY'
import json, sys
w = sys.argv[1]
for v in ("fast-eventnerf", "fast-quiet"):
    rows = [json.loads(l) for l in open(f"{w}/{v}/log.jsonl")]
    assert rows[-1]["event_loss"] < rows[0]["event_loss"], (v, rows[0]["event_loss"], rows[-1]["event_loss"])
q = [json.loads(l) for l in open(f"{w}/fast-quiet/log.jsonl")]
assert all("quiet_loss" in r and "tv_loss" in r for r in q), q[0].keys()
assert all("quiet_loss" not in json.loads(l) for l in open(f"{w}/fast-eventnerf/log.jsonl"))
PY
# Resuming fast-eventnerf's checkpoint as fast-quiet is refused: the losses differ.
if "$EV" train "$work/rec" --out "$work/fast-eventnerf" --variant fast-quiet --resume "${ARGS[@]}" > "$work/wrong.txt" 2>&1; then
  echo "a checkpoint of another loss was resumed"; exit 1
fi
grep -q "trained with the loss" "$work/wrong.txt" || { cat "$work/wrong.txt"; exit 1; }
# A format of the user's own (parts/csv_events.hpp), registered by the program: convert writes it, inspect,
# convert and train read it (by its content, and by --format csv), the events come back the same, and a bad
# line is refused naming the file and the line.
mkdir -p "$work/csv"
"$EV" convert "$work/rec" "$work/csv/events.csv" > /dev/null
[ "$(head -1 "$work/csv/events.csv")" = "t,x,y,p" ] || { echo "convert did not write the CSV format"; exit 1; }
"$EV" convert "$work/csv/events.csv" "$work/csv_back" > /dev/null
cmp -s "$work/rec/events.txt" "$work/csv_back/events.txt" || { echo "the CSV format does not round-trip"; exit 1; }
"$EV" inspect "$work/csv/events.csv" --format csv > "$work/csv_inspect.txt"
grep -q "csv" "$work/csv_inspect.txt" || { cat "$work/csv_inspect.txt"; echo "inspect does not name the CSV format"; exit 1; }
"$EV" train "$work/csv/events.csv" --out "$work/csv_run" --variant fast-eventnerf --iterations 20 --pixels 256 --seed 1 --threads 2 --quiet \
  --allow-collapse --checkpoint-every 0 > "$work/csv_train.txt" 2>&1 || { cat "$work/csv_train.txt"; echo "train refused the CSV file"; exit 1; }
test -s "$work/csv_run/model.ckpt" || { echo "no checkpoint from the CSV file"; exit 1; }
printf 't,x,y,p\n0.1,1,2,1\n0.2,1,y,1\n' > "$work/csv/bad.csv"
if "$EV" inspect "$work/csv/bad.csv" > "$work/csv_bad.txt" 2>&1; then echo "a bad CSV file was read"; exit 1; fi
grep -q "bad.csv:3: value 3 is not a finite number" "$work/csv_bad.txt" || { cat "$work/csv_bad.txt"; echo "the CSV error names no line"; exit 1; }
echo "parts: fast-eventnerf and fast-quiet trained, rendered and evaluated; the CSV format read, written and trained on"
