#!/usr/bin/env bash
# Acceptance figures of the clustering metrics (issue #4), printed as tables:
#  1-3. the MetricAcceptance tests (fandisk Hausdorff and corners, gradation deciles, anisotropic
#       elongation; the larger shared meshes too), which print their figures on "[ metrics  ]" lines;
#  4.   the dragon benchmark: stanford_dragon_vrip.ply -> N vertices, --threads 1, for I, IQ, A, AQ:
#       wall / user CPU / curvature / clustering seconds, peak RSS, Qav, two-sided RMS distance and
#       Hausdorff (streamcvd distance --samples 1000000, relative to the input's bbox diagonal).
# Usage: tools/metrics_acceptance.sh [build-dir] [data-dir] [N]   (defaults: build ../shared/data 20000)
# SKIP_TESTS=1 skips part 1-3, SKIP_DRAGON=1 part 4.
set -uo pipefail
build=${1:-build}
data=${2:-../shared/data}
n=${3:-20000}
bin="$build/streamcvd"
tests="$build/tests/streamcvd_tests"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

echo "# machine: $(nproc) cores; $(uptime | sed 's/.*load/load/')"

if [ -z "${SKIP_TESTS:-}" ]; then
  echo
  echo "## MetricAcceptance tests ($tests)"
  "$tests" --gtest_filter='MetricAcceptance.*' --gtest_also_run_disabled_tests >"$out/tests.log" 2>&1
  rc=$?
  grep '^\[ metrics  \]' "$out/tests.log" | sed 's/^\[ metrics  \] //'
  grep -E '^\[  (PASSED|FAILED) |^\[       OK \]|^\[  FAILED  \]' "$out/tests.log"
  [ $rc -eq 0 ] || echo "tests exit code $rc"
fi

if [ -z "${SKIP_DRAGON:-}" ]; then
  dragon="$data/stanford_dragon_vrip.ply"
  echo
  echo "## Dragon benchmark: $(basename "$dragon") -> $n vertices, --threads 1"
  echo "# load before: $(uptime | sed 's/.*load average: //')"
  printf "%-3s %7s %7s %9s %10s %8s %6s %10s %10s %10s\n" metric wall_s user_s curv_s cluster_s peak_MB Qav \
    rms_in_out rms_out_in hausdorff
  for metric in I IQ A AQ; do
    /usr/bin/time -f "%e %U %M" -o "$out/time_$metric" \
      "$bin" remesh "$dragon" -o "$out/dragon_$metric.ply" -n "$n" --metric "$metric" --threads 1 \
      --report "$out/r_$metric.json" -q 2>"$out/err_$metric"
    if [ $? -ne 0 ]; then
      echo "$metric: remesh failed: $(head -1 "$out/err_$metric")"
      continue
    fi
    "$bin" distance "$dragon" "$out/dragon_$metric.ply" --samples 1000000 --json >"$out/d_$metric.json" 2>"$out/derr" ||
      echo "$metric: distance failed: $(head -1 "$out/derr")"
    python3 - "$metric" "$out/time_$metric" "$out/r_$metric.json" "$out/d_$metric.json" <<'PY'
import json, sys
metric, tfile, rfile, dfile = sys.argv[1:5]
wall, user, rss_kb = open(tfile).read().split()[-3:]
r = json.load(open(rfile)); s = r["seconds"]
try:
    d = json.load(open(dfile))
    dist = "%10.3e %10.3e %10.3e" % (d["a_to_b"]["rms_relative"], d["b_to_a"]["rms_relative"], d["hausdorff_relative"])
except Exception:
    dist = "%10s %10s %10s" % ("-", "-", "-")
print("%-3s %7.2f %7.2f %9.2f %10.2f %8.0f %6.3f %s" % (metric, float(wall), float(user), s["curvature"], s["clustering"],
      int(rss_kb) / 1024, r["quality"]["q_avg"], dist))
PY
  done
  echo "# load after: $(uptime | sed 's/.*load average: //')"
  echo "# rms_in_out: input samples to output surface; rms_out_in: the reverse; all relative to the input bbox diagonal"
  echo "# targets for IQ: wall <= 2.5 s, Qav >= 0.80, RMS <= 3.2e-4 both sides, Hausdorff <= I's"
fi
