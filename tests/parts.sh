#!/usr/bin/env bash
# The parts under examples/parts/ end to end through cli::main (custom_parts): a recording simulated, the
# EventNeRF objective and the quiet-pixels regulariser each trained, rendered and evaluated; the log names the
# regulariser's term, and a variant's checkpoint is refused by the other's loss; eval's output is one table
# unless --verbose.
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
echo "parts: fast-eventnerf and fast-quiet trained, rendered and evaluated"
