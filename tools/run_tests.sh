#!/usr/bin/env bash
# Builds streamcvd (Release) and runs the whole test suite; then a short libFuzzer run of every
# fuzz target (fuzz/run_fuzzers.sh); then the whole suite again built with AddressSanitizer +
# UndefinedBehaviorSanitizer; then the parallel clustering tests built with ThreadSanitizer
# (ParallelClustering* only, to keep the run short). Installs missing Debian packages first.
# The Release ctest includes python_tests (pytest of python/tests against the module built for
# /usr/bin/python3); the sanitizer trees build no Python module (CMake skips it under
# STREAMCVD_SANITIZE: an instrumented extension cannot load into an uninstrumented python).
# Usage: tools/run_tests.sh [build-dir]   (default: build; also uses <build-dir>-fuzz, <build-dir>-asan,
#        <build-dir>-tsan)
# Environment: STREAMCVD_SKIP_FUZZ=1 / STREAMCVD_SKIP_SANITIZE=1 / STREAMCVD_SKIP_TSAN=1 skip a stage;
#              STREAMCVD_FUZZ_SECONDS=N fuzzes each target N seconds (default 60).
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
tools/install_deps.sh
start=$SECONDS
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release
cmake --build "$build" -j"$(nproc)"
ctest --test-dir "$build" --output-on-failure -j"$(nproc)"
echo "run_tests: Release build and tests took $((SECONDS - start)) s"

if [ "${STREAMCVD_SKIP_FUZZ:-0}" != 1 ]; then
  start=$SECONDS
  fuzz/run_fuzzers.sh "$build/streamcvd" "${STREAMCVD_FUZZ_SECONDS:-60}" "$build-fuzz"
  echo "run_tests: fuzzing took $((SECONDS - start)) s"
fi

if [ "${STREAMCVD_SKIP_SANITIZE:-0}" != 1 ]; then
  cmake -S . -B "$build-asan" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSTREAMCVD_SANITIZE=address,undefined
  cmake --build "$build-asan" -j"$(nproc)"
  ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:strict_string_checks=1} UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1} \
    ctest --test-dir "$build-asan" --output-on-failure -j"$(nproc)"
fi

if [ "${STREAMCVD_SKIP_TSAN:-0}" != 1 ]; then
  # Only the test binary: the library's other TBB stages run on one thread in these tests, since
  # TSan cannot see inside the uninstrumented libtbb (see tests/parallel_clustering_test.cpp).
  start=$SECONDS
  cmake -S . -B "$build-tsan" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSTREAMCVD_SANITIZE=thread -DSTREAMCVD_BUILD_TOOLS=OFF
  cmake --build "$build-tsan" -j"$(nproc)" --target streamcvd_tests
  TSAN_OPTIONS=${TSAN_OPTIONS:-halt_on_error=1:second_deadlock_stack=1} \
    "$build-tsan/tests/streamcvd_tests" --gtest_filter='ParallelClustering*'
  echo "run_tests: ThreadSanitizer build and parallel tests took $((SECONDS - start)) s"
fi
