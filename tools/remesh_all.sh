#!/usr/bin/env bash
# Remeshes every mesh of a folder (default ../shared/data) to each N given (default 1000 10000)
# and prints one line per run: exit code, output counts, Qav and the guarantee checks.
# Usage: tools/remesh_all.sh [streamcvd-binary] [data-dir] [N ...]
set -uo pipefail
bin=${1:-build/streamcvd}
data=${2:-../shared/data}
shift 2 2>/dev/null || shift $#
budgets=("$@")
[ ${#budgets[@]} -gt 0 ] || budgets=(1000 10000)
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
failures=0
printf "%-30s %6s %4s %8s %8s %6s %8s %s\n" mesh N rc V F Qav seconds checks
for mesh in "$data"/*.ply "$data"/*.obj "$data"/*.off "$data"/*.stl; do
  [ -f "$mesh" ] || continue
  for n in "${budgets[@]}"; do
    "$bin" remesh "$mesh" -o "$out/out.ply" -n "$n" --report "$out/r.json" -q 2>"$out/err"
    rc=$?
    if [ $rc -ne 0 ]; then
      printf "%-30s %6s %4s %s\n" "$(basename "$mesh")" "$n" "$rc" "$(head -1 "$out/err")"
      failures=$((failures + 1))
      continue
    fi
    python3 - "$out/r.json" "$(basename "$mesh")" "$n" <<'PY'
import json, sys
j = json.load(open(sys.argv[1])); c = j["checks"]
flags = "ok" if c["all_ok"] else "FAILED " + ",".join(k for k in ("manifold_ok", "closed_ok", "genus_preserved", "exact_vertex_count") if c.get(k) is False)
if not c["exact_vertex_count"] and c["all_ok"]: flags += " (vertex count: %s)" % c.get("vertex_count_note", "cleanup")
print("%-30s %6s %4d %8d %8d %6.3f %8.2f %s" % (sys.argv[2], sys.argv[3], 0, j["output"]["vertices"], j["output"]["faces"],
      j["quality"]["q_avg"], j["seconds"]["total"], flags))
PY
  done
done
exit $((failures > 0))
