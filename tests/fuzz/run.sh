#!/usr/bin/env bash
# Builds the libFuzzer harnesses (clang, ASan + UBSan) and runs each for SECONDS seconds (default 60; with
# RUNS set, until RUNS executions or SECONDS, whichever comes first). Inputs: the seed corpora that
# make_seeds writes with evnerf's own writers, the inputs of past findings (tests/fuzz/regressions/<h>/)
# and the corpus kept from earlier runs in $OUT/<h>/corpus. Any crash, sanitizer report, leak, timeout
# (10 s per input) or allocation above 2 GB fails the run; libFuzzer leaves the input as
# crash-*/leak-*/timeout-*/oom-* in $OUT/<h>/. Prints one line per harness: executions, executions per
# second, corpus size.
# Usage: tests/fuzz/run.sh [SECONDS] [HARNESS ...]   Environment: OUT (build-fuzz/runs), BUILD (build-fuzz),
#        RUNS (executions per harness).
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=$PWD
scripts/deps.sh clang libomp-dev libstb-dev
SECONDS_EACH=${1:-60}
shift || true
BUILD=${BUILD:-build-fuzz}
OUT=${OUT:-$BUILD/runs}
BUILD=$(realpath -m "$BUILD")
OUT=$(realpath -m "$OUT")
cmake -S tests/fuzz -B "$BUILD" -G Ninja -DCMAKE_CXX_COMPILER=clang++ >/dev/null
cmake --build "$BUILD" -j"$(nproc)"
HARNESSES=("$@")
[ ${#HARNESSES[@]} -gt 0 ] || HARNESSES=(events calib images poses colmap npy png scene checkpoint)
SEEDS="$BUILD/seeds.$$"  # per invocation: runs may go side by side
trap 'rm -rf "$SEEDS"' EXIT
"$BUILD/make_seeds" "$SEEDS" >/dev/null
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
export OMP_NUM_THREADS=1
status=0
for h in "${HARNESSES[@]}"; do
  dir="$OUT/$h"
  mkdir -p "$dir/corpus"
  dict=()
  case $h in
    scene | colmap | npy | png) dict=(-dict="$ROOT/tests/fuzz/$h.dict") ;;
  esac
  limit=(-max_total_time="$SECONDS_EACH")
  [ -n "${RUNS:-}" ] && limit+=(-runs="$RUNS")
  set +e
  regressions=()
  [ -d "$ROOT/tests/fuzz/regressions/$h" ] && regressions=("$ROOT/tests/fuzz/regressions/$h")
  (cd "$dir" && "$BUILD/fuzz_$h" corpus "$SEEDS/$h" "${regressions[@]}" "${dict[@]}" "${limit[@]}" \
      -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=2048 -max_len=8192 -print_final_stats=1 > log.txt 2>&1)
  rc=$?
  set -e
  runs=$(grep -m1 '^stat::number_of_executed_units' "$dir/log.txt" | awk '{print $2}')
  secs=$(grep -m1 '^stat::average_exec_per_sec' "$dir/log.txt" | awk '{print $2}')
  corpus=$(ls "$dir/corpus" | wc -l)
  if [ $rc -ne 0 ]; then
    status=1
    echo "fuzz_$h: FAILED (exit $rc) after ${runs:-?} executions; see $dir/log.txt and $dir/crash-* etc."
    grep -m3 -E "ERROR|SUMMARY|invariant|error message" "$dir/log.txt" || true
  else
    echo "fuzz_$h: ${runs:-?} executions (${secs:-?}/s), corpus $corpus inputs, no crash, leak, hang or oversized allocation"
  fi
done
exit $status
