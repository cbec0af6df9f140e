#!/usr/bin/env bash
# The unit-test suite (evnerf_tests: every doctest case) built with AddressSanitizer + UndefinedBehavior-
# Sanitizer, any report fatal. `.ci/run` runs it after the Release suite. The CLI tests, failtests and the
# consumer stay with the Release build: they exercise the build system and argument parsing, not memory.
# Usage: scripts/sanitize.sh [SANITIZERS]   (default address,undefined; 'thread' for ThreadSanitizer, built
#        with LLVM's OpenMP runtime in build-tsan: see below). Built with clang.
# Environment: BUILD (build-sanitize), TESTS (a doctest -tc filter, default all), SUBSET (test files to
# build, default all; .ci/run passes the readers', events', evaluation's, simulator's, compositing's and
# objectives' files, which fit its time limit: the model, network and training files take most of the
# sanitized compile time on two cores).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh
SAN=${1:-address,undefined}
BUILD=${BUILD:-build-sanitize}
# clang for every sanitizer: it compiles the instrumented suite in about two thirds of GCC's time (GCC's
# UndefinedBehaviorSanitizer doubles the compile), and ThreadSanitizer sees OpenMP's synchronisation only
# through LLVM's libomp with its Archer tool (GCC's libgomp is not instrumented and reports false races).
scripts/deps.sh clang libomp-dev
COMPILER=(-DCMAKE_CXX_COMPILER=clang++)
if [ "$SAN" = thread ]; then
  BUILD=${BUILD/%build-sanitize/build-tsan}
  export OMP_TOOL_LIBRARIES=${OMP_TOOL_LIBRARIES:-$(realpath "$(clang++ -print-resource-dir)/../../libarcher.so")}
  export TSAN_OPTIONS=${TSAN_OPTIONS:-ignore_noninstrumented_modules=1:halt_on_error=1:second_deadlock_stack=1:history_size=4}
  export ARCHER_OPTIONS=${ARCHER_OPTIONS:-verbose=1}
fi
# Release with sanitizers builds at -O2 with line tables (CMakeLists.txt, EVNERF_SANITIZE): the suite checks
# some fast paths bit for bit against their references, which holds at -O2 and -O3.
cmake -S . -B "$BUILD" -G Ninja "${COMPILER[@]}" -DCMAKE_BUILD_TYPE=Release -DEVNERF_SANITIZE="$SAN" \
  -DEVNERF_BUILD_EXAMPLES=OFF -DEVNERF_BUILD_TESTS=ON -DEVNERF_TEST_SUBSET="${SUBSET:-}" >/dev/null
cmake --build "$BUILD" -j"$(nproc)" --target evnerf_tests
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:strict_string_checks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-2}
"$BUILD/tests/evnerf_tests" ${TESTS:+-tc="$TESTS"}
