#!/usr/bin/env bash
# The sweep example without Slurm (examples/slurm/sweep.sh as a plain loop, then gather.py): 2 scenes ×
# 2 presets × 1 seed on a small sensor; every task leaves metrics.json, the table has a row per (scene,
# preset); a rerun skips the finished tasks and redoes only one whose metrics.json is gone; a bad task index
# is refused; a task under a Slurm array index runs just that task; the paired table (--against) of a
# made-up tree gives the known differences. Usage: sweep.sh EVNERF_BINARY
set -euo pipefail
EVNERF=$(realpath "$1")
HERE="$(cd "$(dirname "$0")" && pwd)"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
export EVNERF OUT="$work/out" SCENES="planes object" PRESETS="fast no-joint" SEEDS="1" ITERS=15 THREADS=2 WIDTH=48 HEIGHT=36
sweep="$HERE/../examples/slurm/sweep.sh"
bash "$sweep" >"$work/first.txt" 2>&1 || { cat "$work/first.txt"; fail "the loop failed"; }
grep -q "4 tasks (2 scenes × 2 presets × 1 seeds)" "$work/first.txt" || fail "the loop did not announce 4 tasks"
for s in planes object; do
  for p in fast no-joint; do
    [ -f "$OUT/$s/$p/seed1/metrics.json" ] || fail "no metrics.json for $s $p"
  done
done
python3 "$HERE/../examples/slurm/gather.py" "$OUT" --csv "$work/all.csv" >"$work/table.txt"
[ "$(grep -c '^| \(planes\|object\) |' "$work/table.txt")" = 4 ] || { cat "$work/table.txt"; fail "the table does not have 4 rows"; }
grep -q "alignment global-log-affine" "$work/table.txt" || fail "the table does not state its alignment"
grep -q "| coarse PSNR | fine PSNR |" "$work/table.txt" || fail "the table does not split the error by scale"
python3 - "$work/all.csv" <<'PY' || fail "the CSV's coarse and fine PSNR are not numbers"
import csv, sys
for r in csv.DictReader(open(sys.argv[1])):
    assert float(r["coarse_psnr"]) > 0 and float(r["fine_psnr"]) > 0, r
PY
[ "$(wc -l <"$work/all.csv")" = 5 ] || fail "the CSV does not have 4 runs"
# Rerun: finished tasks are skipped; a task without metrics.json is redone (resuming its checkpoint).
rm "$OUT/object/fast/seed1/metrics.json"
bash "$sweep" >"$work/second.txt" 2>&1 || { cat "$work/second.txt"; fail "the rerun failed"; }
[ "$(grep -c 'done before, skipped' "$work/second.txt")" = 3 ] || { cat "$work/second.txt"; fail "the rerun did not skip 3 tasks"; }
[ -f "$OUT/object/fast/seed1/metrics.json" ] || fail "the rerun did not redo the task"
# One task by index, as a Slurm array task would run it.
rm "$OUT/planes/no-joint/seed1/metrics.json"
SLURM_ARRAY_TASK_ID=1 bash "$sweep" >"$work/third.txt" 2>&1 || fail "the array task failed"
grep -q "task 1 (planes, no-joint, seed 1)" "$work/third.txt" && [ "$(grep -c '^task' "$work/third.txt")" = 1 ] || { cat "$work/third.txt"; fail "the array task did not run task 1 alone"; }
if bash "$sweep" 9 >"$work/bad.txt" 2>&1; then fail "task 9 of 4 was accepted"; fi
grep -q "task '9' is not one of 0..3" "$work/bad.txt" || fail "task 9: no clear error"
# The paired table (--against) on a made-up tree of known figures: preset b minus preset a at the seeds
# both have (seed 3 has no run of a), an infinite coarse part (an error-free part) shown as no difference.
fake="$work/fake"
metrics() {  # scene preset seed psnr ssim coarse fine
  mkdir -p "$fake/$1/$2/seed$3"
  printf '{"alignment": "global-log-affine", "methods": {"evnerf_%s": {"psnr": %s, "ssim": %s}, "direct_integration": {"psnr": 10, "ssim": 0.1}, "high_pass_filter": {"psnr": 11, "ssim": 0.2}}, "error_scales": {"methods": {"evnerf_%s": {"coarse_psnr": %s, "fine_psnr": %s}}}}' \
    "$2" "$4" "$5" "$2" "$6" "$7" >"$fake/$1/$2/seed$3/metrics.json"
}
metrics planes a 1 20 0.80 25 22
metrics planes a 2 21 0.81 26 23
metrics planes b 1 21 0.83 27 23.5
metrics planes b 2 20.5 0.80 null 22.5
metrics planes b 3 30 0.90 30 30
python3 "$HERE/../examples/slurm/gather.py" "$fake" --against a >"$work/paired.txt" || { cat "$work/paired.txt"; fail "gather --against failed"; }
grep -qF "| planes | b | 1,2 | +0.25 ± 1.06 | +0.010 ± 0.028 | — | +0.50 ± 1.41 | 1 of 2 | 1: +1.00, 2: -0.50 |" "$work/paired.txt" \
  || { cat "$work/paired.txt"; fail "the paired table's row is not b minus a at seeds 1 and 2"; }
grep -qF "| planes | b | 1,2,3 | 23.83 ± 5.35 | 0.843 ± 0.051 | inf |" "$work/paired.txt" || fail "an error-free part is not shown as inf"
if python3 "$HERE/../examples/slurm/gather.py" "$fake" --against c >"$work/nopreset.txt" 2>&1; then fail "--against a preset with no run was accepted"; fi
grep -q "no run of that preset" "$work/nopreset.txt" || fail "--against c: no clear error"
echo "sweep: 4 tasks in a plain loop, gathered into one table; reruns skip finished tasks; array task and bad index handled; paired table right"
