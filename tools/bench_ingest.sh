#!/usr/bin/env bash
# Ingest benchmark (not a test): builds the compact store of the Stanford dragon (ascii PLY), a
# generated 10M-face binary PLY torus, and the dragon subdivided 3x3 (7.8M faces) and 11x11 (105M
# faces, 2.0 GB) by ../shared/tools/genbig, each inside a memory cgroup (../shared/tools/memlimit,
# default 1G): input MB/s, wall and cpu time, and the cgroup's peak. With IDENTITY=1 it also
# checks that stores built at --memory 64M and unlimited are byte-identical (torus, dragon x9).
# Usage:
#   tools/bench_ingest.sh [WORK_DIR]
# Env: STREAMCVD (binary; default build/streamcvd), MEMLIMIT (1G; "none" runs without a cgroup),
#      CASES (default "dragon torus d3 d11"), RUNS (1), IDENTITY (0), COLD=1 drops the page cache
#      before each run (root only: then the input comes from the disk, not from RAM), KEEP=1 keeps
#      the stores, SHARED (../shared). Needs /usr/bin/time.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
STREAMCVD="${STREAMCVD:-$here/../build/streamcvd}"
SHARED="${SHARED:-$here/../../shared}"
[[ -x "$STREAMCVD" ]] || { echo "set STREAMCVD to the streamcvd binary" >&2; exit 2; }
[[ -x /usr/bin/time ]] || { echo "/usr/bin/time is required (apt-get install time)" >&2; exit 2; }
work="${1:-${TMPDIR:-/tmp}/streamcvd_bench_ingest}"
mkdir -p "$work"
MEMLIMIT="${MEMLIMIT:-1G}"
dragon="$SHARED/data/stanford_dragon_vrip.ply"

input_of() {  # generates the case's input once
  case "$1" in
    dragon) echo "$dragon" ;;
    torus)
      local t="$work/torus_2236.ply"
      [[ -s "$t" ]] || "$STREAMCVD" generate torus --rings 2236 --segments 2236 -o "$t" >&2
      echo "$t" ;;
    d3 | d11)
      local k=${1#d} f="$work/dragon_x$(( ${1#d} * ${1#d} )).ply"
      [[ -s "$f" ]] || "$SHARED/tools/genbig" "$dragon" "$f" "$k" >&2
      echo "$f" ;;
  esac
}

# Runs one ingest (extra args after the store) inside the cgroup; prints one line.
run_ingest() {
  local name="$1" input="$2" store="$3"; shift 3
  rm -rf "$store"
  [[ "${COLD:-0}" == 1 ]] && sync && echo 3 >/proc/sys/vm/drop_caches
  local load wrap=()
  load=$(cut -d' ' -f1 /proc/loadavg)
  [[ "$MEMLIMIT" != none ]] && wrap=("$SHARED/tools/memlimit" "$MEMLIMIT")
  /usr/bin/time -f "%e %U %S" -o "$work/time" "${wrap[@]}" "$STREAMCVD" ingest "$input" "$store" --json "$@" \
    >"$work/json" 2>"$work/err" || { cat "$work/err" >&2; return 1; }
  local wall user sys peak in_bytes
  read -r wall user sys <"$work/time"
  peak=$(sed -n 's/.*peak \([^,]*\),.*/\1/p' "$work/err")
  in_bytes=$(stat -L -c %s "$input")  # -L: an input may be a symlink to a shared copy
  awk -v n="$name" -v ib="$in_bytes" -v w="$wall" -v u="$user" -v s="$sys" -v pk="${peak:-n/a}" -v ld="$load" \
      -v lim="$MEMLIMIT" -v extra="$*" 'BEGIN {
    printf "%-7s %-14s input %8.1f MB  wall %6.2f s  cpu %6.2f s (user %6.2f + sys %5.2f, load %4.2f)  %6.1f MB/s  cgroup %s peak %s\n",
           n, extra, ib / 1e6, w, u + s, u, s, ld, ib / 1e6 / (w > 0 ? w : 1e-9), lim, pk }'
}

echo "streamcvd: $STREAMCVD   cores: $(nproc)   load: $(cut -d' ' -f1-3 /proc/loadavg)   memlimit: $MEMLIMIT"
for case in ${CASES:-dragon torus d3 d11}; do
  input=$(input_of "$case")
  for ((run = 1; run <= ${RUNS:-1}; ++run)); do run_ingest "$case" "$input" "$work/$case.store"; done
  grep -o '"spilled_bytes": [0-9]*\|"key_buckets": [0-9]*\|"vertex_ranges": [0-9]*' "$work/json" | tr '\n' ' '
  echo
  if [[ "${IDENTITY:-0}" == 1 && ( "$case" == torus || "$case" == d3 ) ]]; then
    MEMLIMIT=none run_ingest "$case" "$input" "$work/$case.64m.store" --memory 64M
    if diff -rq "$work/$case.store" "$work/$case.64m.store" >/dev/null; then
      echo "        --memory 64M and unlimited: byte-identical stores"
    else
      echo "        --memory 64M and unlimited: STORES DIFFER" && diff -rq "$work/$case.store" "$work/$case.64m.store" || true
    fi
    rm -rf "$work/$case.64m.store"
  fi
  [[ "${KEEP:-0}" == 1 ]] || rm -rf "$work/$case.store"
done
