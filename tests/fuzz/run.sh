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
scripts/deps.sh clang libomp-dev libstb-dev libhdf5-dev libbz2-dev liblz4-dev libzstd-dev
SECONDS_EACH=${1:-60}
shift || true
BUILD=${BUILD:-build-fuzz}
OUT=${OUT:-$BUILD/runs}
BUILD=$(realpath -m "$BUILD")
OUT=$(realpath -m "$OUT")
cmake -S tests/fuzz -B "$BUILD" -G Ninja -DCMAKE_CXX_COMPILER=clang++ >/dev/null
cmake --build "$BUILD" -j"$(nproc)"
HARNESSES=("$@")
# fuzz_hdf5 runs by name only (`run.sh SECONDS hdf5`): it finds memory errors inside Debian's libhdf5 1.10.8
# itself (a heap over-read in H5Aexists on a corrupt object header, after 21 k inputs), which evnerf cannot
# fix; io::load isolates the library's crashes in a child process (README, Reliability).
[ ${#HARNESSES[@]} -gt 0 ] || HARNESSES=(events calib images poses colmap npy png scene checkpoint rosbag npz layouts prophesee aedat4 ply frame)
SEEDS="$BUILD/seeds.$$"  # per invocation: runs may go side by side
trap 'rm -rf "$SEEDS"' EXIT
"$BUILD/make_seeds" "$SEEDS" >/dev/null
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$ROOT/tests/fuzz/lsan.supp:print_suppressions=0}
export OMP_NUM_THREADS=1
# One harness: its run, and its one line in $OUT/<h>/summary.txt.
fuzz_one() {
  local h=$1
  local dir="$OUT/$h"
  mkdir -p "$dir/corpus" "$SEEDS/$h"
  local dict=() limit regressions memory asan max_len rc runs secs corpus
  rm -f "$dir/summary.txt"
  case $h in
    scene | colmap | npy | png | rosbag | layouts) dict=(-dict="$ROOT/tests/fuzz/$h.dict") ;;
  esac
  limit=(-max_total_time="$SECONDS_EACH")
  [ -n "${RUNS:-}" ] && limit+=(-runs="$RUNS")
  set +e
  regressions=()
  [ -d "$ROOT/tests/fuzz/regressions/$h" ] && regressions=("$ROOT/tests/fuzz/regressions/$h")
  memory=(-malloc_limit_mb=2048)
  asan=$ASAN_OPTIONS
  max_len=8192
  if [ "$h" = hdf5 ]; then
    regressions+=("$ROOT/tests/fixtures")  # files written by h5py
    # The HDF5 library sizes its metadata cache from the file's headers: on a corrupt file it asks for
    # tens of GB, and a failed malloc is an error it reports. Allocations above 2 GB therefore fail (return
    # null, or throw std::bad_alloc in C++, which the harness treats as a crash) as on a machine without
    # that memory, instead of stopping the run.
    memory=(-malloc_limit_mb=1000000)
    asan="$ASAN_OPTIONS:allocator_may_return_null=1:max_allocation_size_mb=2048:exitcode=99"
    max_len=32768  # the h5py fixtures are 6 and 20 kB
    export HDF5_DEFECTS="$dir/libhdf5_defects"  # the library's own defects the child contained (fuzz_hdf5.cpp)
  fi
  if [ "$h" = npz ]; then
    for z in "$ROOT"/tests/fixtures/eventnerf*/train/events/*.npz; do cp "$z" "$SEEDS/$h/$(basename "$(dirname "$(dirname "$(dirname "$z")")")").npz"; done  # numpy's
    for z in "$ROOT"/tests/fixtures/robust_e_nerf/*.npz; do cp "$z" "$SEEDS/$h/ren_$(basename "$z")"; done
  fi
  if [ "$h" = layouts ]; then  # whole folders written by numpy, in fuzz_layouts' one-input form
    r="$ROOT/tests/fixtures/robust_e_nerf"
    { printf R; cat "$r/camera_calibration.npz"; printf '@@next@@'; cat "$r/raw_events.npz"; printf '@@next@@'; cat "$r/camera_poses.npz"; } >"$SEEDS/$h/robust_e_nerf"
    for e in "$ROOT"/tests/fixtures/eventnerf*/train; do
      { printf E; cat "$e"/events/*.npz; printf '@@next@@'; cat "$e/intrinsics/r_00000.txt"
        for p in "$e"/pose/*.txt; do printf '@@next@@'; cat "$p"; done; } >"$SEEDS/$h/$(basename "$(dirname "$e")")"
    done
  fi
  if [ "$h" = aedat4 ]; then
    max_len=16384  # the seeds hold 300 events and two frames
  fi
  if [ "$h" = rosbag ]; then
    for b in "$ROOT"/tests/fixtures/*.bag; do cp "$b" "$SEEDS/$h/"; done  # bags written by python3-rosbag
    max_len=40000  # the fixtures are 20 to 33 kB
  fi
  (cd "$dir" && ASAN_OPTIONS=$asan "$BUILD/fuzz_$h" corpus "$SEEDS/$h" "${regressions[@]}" "${dict[@]}" "${limit[@]}" \
      -timeout=10 -rss_limit_mb=2048 "${memory[@]}" -max_len=$max_len -print_final_stats=1 > log.txt 2>&1)
  rc=$?
  set -e
  # The last figures are the run's: fuzz_hdf5's forked children print theirs into the same log first.
  runs=$(grep -a '^stat::number_of_executed_units' "$dir/log.txt" | tail -1 | awk '{print $2}' || true)
  secs=$(grep -a '^stat::average_exec_per_sec' "$dir/log.txt" | tail -1 | awk '{print $2}' || true)
  corpus=$(ls "$dir/corpus" | wc -l)
  if [ $rc -ne 0 ]; then
    { echo "fuzz_$h: FAILED (exit $rc) after ${runs:-?} executions; see $dir/log.txt and $dir/crash-* etc."
      grep -m3 -E "ERROR|SUMMARY|invariant|error message" "$dir/log.txt" || true; } > "$dir/summary.txt"
  else
    defects=""
    [ -d "$dir/libhdf5_defects" ] && defects="; libhdf5's own defects contained in the child: $(ls "$dir/libhdf5_defects" | grep -c '\.h5$') inputs in $dir/libhdf5_defects"
    echo "fuzz_$h: ${runs:-?} executions (${secs:-?}/s), corpus $corpus inputs, no crash, leak, hang or oversized allocation$defects" > "$dir/summary.txt"
  fi
}
# The harnesses run side by side, one per core (JOBS, default nproc; each is single-threaded), each for
# its SECONDS; their lines are printed in order once all have ended.
# (nproc honours OMP_NUM_THREADS, which is 1 here for the harnesses: ask it without.)
JOBS=${JOBS:-$(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc)}
for h in "${HARNESSES[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$JOBS" ]; do wait -n || true; done
  fuzz_one "$h" &
done
wait
status=0
for h in "${HARNESSES[@]}"; do
  if [ -f "$OUT/$h/summary.txt" ]; then
    cat "$OUT/$h/summary.txt"
    grep -q "^fuzz_$h: FAILED" "$OUT/$h/summary.txt" && status=1
  else
    echo "fuzz_$h: FAILED (the run left no summary)"
    status=1
  fi
done
exit $status
