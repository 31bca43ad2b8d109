#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan+UBSan) and runs each for a while from the seed corpus.
# Usage: fuzz/run_fuzzers.sh STREAMCVD_CLI [SECONDS_PER_TARGET=60] [BUILD_DIR=build-fuzz] [TARGETS...]
#   STREAMCVD_CLI  a built streamcvd (any build type), used to generate the seed corpus
# Runs two targets at a time. Exits 1 if any target reports a crash, leak, timeout or OOM; the
# input is then in BUILD_DIR/fuzz-artifacts/<target>/ (add it to tests/data/fuzz_regressions/).
# Corpora grow in BUILD_DIR/fuzz-corpus/<target>/ and are reused by the next run.
set -euo pipefail
cd "$(dirname "$0")/.."
cli=$(realpath "$1")
seconds=${2:-60}
build=${3:-build-fuzz}
shift $(( $# < 3 ? $# : 3 ))
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(fuzz_ply fuzz_obj fuzz_off fuzz_stl fuzz_store)

CXX=${FUZZ_CXX:-clang++-14} cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DSTREAMCVD_BUILD_FUZZERS=ON -DSTREAMCVD_BUILD_TESTS=OFF -DSTREAMCVD_BUILD_TOOLS=OFF >/dev/null
cmake --build "$build" -j2 --target "${targets[@]}"

seeds="$build/fuzz-seeds"
rm -rf "$seeds"
fuzz/make_corpus.sh "$cli" "$seeds"

run_one() {
  local t=$1 kind=${1#fuzz_}
  local corpus="$build/fuzz-corpus/$t" artifacts="$build/fuzz-artifacts/$t"
  mkdir -p "$corpus" "$artifacts"
  # -timeout: one input taking over 10 s is a hang; -rss_limit_mb: over 2 GiB is an allocation
  # sized from a header.
  local pid rc=0
  "$build/fuzz/$t" "$corpus" "$seeds/$kind" -max_total_time="$seconds" -max_len=16384 -timeout=10 \
    -rss_limit_mb=2048 -artifact_prefix="$artifacts/" -print_final_stats=1 >"$build/fuzz-$t.log" 2>&1 &
  pid=$!
  wait "$pid" || rc=$?
  # libFuzzer may leave without running destructors: remove the harness's scratch folder.
  rm -rf "/dev/shm/streamcvd_fuzz_$pid" "/tmp/streamcvd_fuzz_$pid"
  if [ "$rc" -eq 0 ]; then
    echo "$t: ok, $(grep -m1 -o 'number_of_executed_units: [0-9]*' "$build/fuzz-$t.log" | grep -o '[0-9]*$') executions"
  else
    echo "$t: FAILED (see $build/fuzz-$t.log and $artifacts/)"
    tail -n 40 "$build/fuzz-$t.log"
    return 1
  fi
}

status=0
pids=()
for t in "${targets[@]}"; do
  run_one "$t" &
  pids+=($!)
  if [ ${#pids[@]} -eq 2 ]; then
    wait "${pids[0]}" || status=1
    pids=("${pids[1]}")
  fi
done
for p in "${pids[@]}"; do wait "$p" || status=1; done
exit $status
