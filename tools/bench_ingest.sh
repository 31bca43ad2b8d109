#!/usr/bin/env bash
# Ingest benchmark (not a test): builds the compact store of a generated ~10M-face binary PLY
# torus and of the Stanford dragon, printing input throughput and peak memory against the store
# size. Usage:
#   STREAMCVD=/path/to/streamcvd tools/bench_ingest.sh [WORK_DIR]
# Needs `$STREAMCVD ingest IN STORE_DIR --json` and /usr/bin/time. The torus comes from
# `$STREAMCVD generate torus` when available, else from a python3 one-off (slow but dependency-free).
# Env: RINGS/SEGMENTS (default 2236 x 2236 = 10.0M faces), DRAGON (path), KEEP=1 keeps the stores,
# RUNS (default 1) ingests of each input, DISK=0 skips the disk bound: the time dd takes to write
# as many bytes as the torus store, past the page cache (as the store writer does) and buffered +
# fsync, which bounds what any ingest writing that store durably can reach. Each line shows the
# 1-minute load average before the run: with other work on this 2-core machine the wall time (and
# MB/s) suffers while the cpu time (user + sys) stays comparable.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
STREAMCVD="${STREAMCVD:-}"
if [[ -z "$STREAMCVD" ]]; then
  for c in "$here/../build/streamcvd" "$here/../build/tools/streamcvd"; do [[ -x "$c" ]] && STREAMCVD="$c" && break; done
fi
[[ -n "$STREAMCVD" && -x "$STREAMCVD" ]] || { echo "set STREAMCVD to the streamcvd binary" >&2; exit 2; }
[[ -x /usr/bin/time ]] || { echo "/usr/bin/time is required (apt-get install time)" >&2; exit 2; }

work="${1:-${TMPDIR:-/tmp}/streamcvd_bench_ingest}"
mkdir -p "$work"
RINGS="${RINGS:-2236}"
SEGMENTS="${SEGMENTS:-2236}"
DRAGON="${DRAGON:-$here/../../shared/data/stanford_dragon_vrip.ply}"
torus="$work/torus_${RINGS}x${SEGMENTS}.ply"

generate_with_python() {  # binary little-endian PLY torus, same layout as core/shapes.cpp make_torus
  python3 - "$1" "$RINGS" "$SEGMENTS" <<'EOF'
import math, struct, sys
from array import array
path, rings, segs = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
R, r = 1.0, 0.35
with open(path, "wb") as f:
    f.write(f"ply\nformat binary_little_endian 1.0\nelement vertex {rings*segs}\nproperty float x\n"
            f"property float y\nproperty float z\nelement face {2*rings*segs}\n"
            f"property list uchar int vertex_indices\nend_header\n".encode())
    for i in range(rings):
        u = 2 * math.pi * i / rings
        row = array("f")
        for j in range(segs):
            w = 2 * math.pi * j / segs
            row.extend(((R + r * math.cos(w)) * math.cos(u), (R + r * math.cos(w)) * math.sin(u), r * math.sin(w)))
        f.write(row.tobytes())
    rec = struct.Struct("<BiiiBiii")
    for i in range(rings):
        i1 = (i + 1) % rings
        out = bytearray()
        for j in range(segs):
            j1 = (j + 1) % segs
            a, b, c, d = i * segs + j, i1 * segs + j, i1 * segs + j1, i * segs + j1
            out += rec.pack(3, a, b, c, 3, a, c, d)
        f.write(out)
EOF
}

if [[ ! -s "$torus" ]]; then
  echo "generating $torus ..." >&2
  if ! "$STREAMCVD" generate torus --rings "$RINGS" --segments "$SEGMENTS" -o "$torus" 2>/dev/null; then
    generate_with_python "$torus"
  fi
fi

# One ingest under /usr/bin/time -v: prints a summary line.
bench() {
  local input="$1" name="$2" store="$work/$2.store" log="$work/$2.time" json="$work/$2.json"
  rm -rf "$store"
  local load
  load=$(cut -d' ' -f1 /proc/loadavg)  # other work on the machine shows in the wall time, not in cpu
  /usr/bin/time -v -o "$log" "$STREAMCVD" ingest "$input" "$store" --json >"$json"
  local in_bytes store_bytes wall peak_kb user sys
  in_bytes=$(stat -c %s "$input")
  store_bytes=$(du -sb "$store" | cut -f1)
  wall=$(awk -F': ' '/Elapsed \(wall clock\)/ {n = split($2, t, ":"); s = 0; for (i = 1; i <= n; ++i) s = s * 60 + t[i]; print s}' "$log")
  user=$(awk -F': ' '/User time/ {print $2}' "$log")
  sys=$(awk -F': ' '/System time/ {print $2}' "$log")
  peak_kb=$(awk -F': ' '/Maximum resident set size/ {print $2}' "$log")
  awk -v n="$name" -v ib="$in_bytes" -v sb="$store_bytes" -v w="$wall" -v u="$user" -v s="$sys" -v pk="$peak_kb" -v ld="$load" 'BEGIN {
    printf "%-8s input %8.1f MB  store %8.1f MB  wall %6.2f s (cpu %5.2f s = user %5.2f + sys %5.2f, load %5.2f)  %7.1f MB/s of input  peak RSS %8.1f MB = %.2f x store\n",
           n, ib / 1e6, sb / 1e6, w, u + s, u, s, ld, ib / 1e6 / (w > 0 ? w : 1e-9), pk * 1024 / 1e6, pk * 1024 / sb }'
  [[ -s "$json" ]] && echo "         $(tr -d '\n' <"$json")"
  [[ "${KEEP:-0}" == 1 ]] || rm -rf "$store"
}

# Disk bound: write `bytes` bytes of the torus file's contents (not zeros, which a virtual disk
# may special-case) durably, like the store writer (O_DIRECT) and like a plain buffered writer.
# The source is prepared first, so dd reads it from the page cache.
disk_bound() {
  local bytes="$1" src="$work/disk_bound.src" out="$work/disk_bound.bin" mode t
  (while cat "$torus"; do :; done 2>/dev/null || true) | head -c "$bytes" >"$src"
  cat "$src" >/dev/null
  for mode in direct buffered; do
    local flags="conv=fsync"
    [[ "$mode" == direct ]] && flags+=" oflag=direct"
    rm -f "$out"
    sync
    /usr/bin/time -f %e -o "$work/disk_bound.time" dd if="$src" of="$out" bs=4M $flags 2>/dev/null
    t=$(tail -1 "$work/disk_bound.time")
    awk -v m="$mode" -v b="$bytes" -v t="$t" 'BEGIN {
      printf "disk     %-8s dd of %8.1f MB with fsync: %6.2f s = %7.1f MB/s\n", m, b / 1e6, t, b / 1e6 / (t > 0 ? t : 1e-9) }'
  done
  rm -f "$out" "$src" "$work/disk_bound.time"
}

echo "streamcvd: $STREAMCVD   cores: $(nproc)   load: $(cut -d' ' -f1-3 /proc/loadavg)"
for ((run = 1; run <= ${RUNS:-1}; ++run)); do
  bench "$torus" torus
  if [[ -s "$DRAGON" ]]; then bench "$DRAGON" dragon; else echo "dragon not found at $DRAGON (set DRAGON=...)" >&2; fi
done
if [[ "${DISK:-1}" != 0 ]]; then
  store_bytes=$(awk -F': ' '/"store_bytes"/ {gsub(/[ ,]/, "", $2); print $2}' "$work/torus.json")
  [[ -n "$store_bytes" ]] && disk_bound "$store_bytes"
fi
