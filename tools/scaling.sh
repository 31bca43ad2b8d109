#!/usr/bin/env bash
# Thread scaling of `streamcvd remesh` (not a test): runs T = 1, 2, 4, … up to nproc (and nproc
# itself) on one mesh, RUNS times each (round-robin over T, so that load drift hits every T alike),
# and prints the medians of the clustering stage's wall and CPU time, the total time, the speed-ups
# over T = 1, the CPU seconds per thread and the clustering energy. On a busy machine, compare the
# CPU column: CPU ≈ T × wall means the threads really ran in parallel.
# Usage: tools/scaling.sh [MESH]   (default: ../shared/data/stanford_dragon_vrip.ply)
# Env: STREAMCVD (binary; default build/streamcvd), N (20000), METRIC (IQ), RUNS (5),
#      THREADS (list, default "1 2 4 … nproc"), EXTRA (more remesh options, e.g. --deterministic),
#      WORK (folder for outputs and reports; default a temporary folder, removed unless KEEP=1).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
STREAMCVD="${STREAMCVD:-}"
if [[ -z "$STREAMCVD" ]]; then
  for c in "$here/../build/streamcvd" "$here/../build/tools/streamcvd"; do [[ -x "$c" ]] && STREAMCVD="$c" && break; done
fi
[[ -n "$STREAMCVD" && -x "$STREAMCVD" ]] || { echo "set STREAMCVD to the streamcvd binary" >&2; exit 2; }
command -v python3 > /dev/null || { echo "python3 is required for the table" >&2; exit 2; }

mesh="${1:-$here/../../shared/data/stanford_dragon_vrip.ply}"
[[ -r "$mesh" ]] || { echo "cannot read $mesh" >&2; exit 2; }
N="${N:-20000}"
METRIC="${METRIC:-IQ}"
RUNS="${RUNS:-5}"
cores=$(nproc)
if [[ -z "${THREADS:-}" ]]; then
  THREADS=""
  for ((t = 1; t < cores; t *= 2)); do THREADS+="$t "; done
  THREADS+="$cores"
fi
if [[ -n "${WORK:-}" ]]; then work="$WORK"; mkdir -p "$work"; else work=$(mktemp -d); fi
[[ "${KEEP:-0}" == 1 || -n "${WORK:-}" ]] || trap 'rm -rf "$work"' EXIT

echo "scaling: $(basename "$mesh") -> N=$N, metric $METRIC, threads {$THREADS}, $RUNS runs each ${EXTRA:-}"
echo "scaling: $cores cores; load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
for ((r = 1; r <= RUNS; ++r)); do
  for t in $THREADS; do
    # shellcheck disable=SC2086
    "$STREAMCVD" remesh "$mesh" -o "$work/out_t${t}.ply" -n "$N" --metric "$METRIC" --threads "$t" -q \
      --report "$work/report_t${t}_r${r}.json" ${EXTRA:-}
  done
done
echo "scaling: load average at end: $(cut -d' ' -f1-3 /proc/loadavg)"

python3 - "$work" "$RUNS" $THREADS <<'PY'
import json, statistics, sys
work, runs, threads = sys.argv[1], int(sys.argv[2]), [int(t) for t in sys.argv[3:]]
rows = {}
for t in threads:
    reps = [json.load(open(f"{work}/report_t{t}_r{r}.json")) for r in range(1, runs + 1)]
    med = lambda f: statistics.median(f(j) for j in reps)
    rows[t] = {
        "clustering": med(lambda j: j["seconds"]["clustering"]),
        "cpu": med(lambda j: j["seconds"].get("clustering_cpu", float("nan"))),
        "total": med(lambda j: j["seconds"]["total"]),
        "energy": med(lambda j: j["clustering"].get("clustering_energy", j["clustering"]["final_energy"])),
        "final": med(lambda j: j["clustering"]["final_energy"]),
        "ok": all(j["checks"]["all_ok"] for j in reps),
    }
base = rows[threads[0]]
print(f"{'T':>4} {'clustering s':>13} {'speed-up':>9} {'CPU s':>8} {'CPU/T/wall':>10} {'total s':>8} {'speed-up':>9}"
      f" {'clustering energy':>18} {'vs T=' + str(threads[0]):>9} {'checks':>7}")
for t in threads:
    r = rows[t]
    print(f"{t:>4} {r['clustering']:>13.3f} {base['clustering'] / r['clustering']:>8.2f}x {r['cpu']:>8.3f}"
          f" {r['cpu'] / t / r['clustering']:>10.2f} {r['total']:>8.3f} {base['total'] / r['total']:>8.2f}x"
          f" {r['energy']:>18.6e} {100 * (r['energy'] - base['energy']) / base['energy']:>+8.3f}% {'ok' if r['ok'] else 'FAIL':>7}")
print("medians of", runs, "runs; CPU = process CPU seconds during the clustering stage (all threads);"
      " CPU/T/wall near 1 = T threads busy, well below 1 = waiting for cores or serial parts")
PY
