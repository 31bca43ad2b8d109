#!/usr/bin/env bash
# Builds the seed corpora of the fuzz targets from small generated meshes (every format and
# variant the readers know) and truncated copies of the bundled meshes.
# Usage: fuzz/make_corpus.sh STREAMCVD_CLI OUT_DIR   (OUT_DIR/<target>/ is created per target)
# Each mesh seed is stored twice: plain (mode byte 0) and zstd-compressed by the harness (mode 1);
# see fuzz/fuzz_common.h. Store seeds are a mode byte 0 + header.bin + the arrays in order.
set -euo pipefail
cli=$1
out=$2
here=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$out"/{ply,obj,off,stl,store}

seed() {  # seed TARGET NAME FILE: the file with mode bytes 0 and 1
  printf '\x00' | cat - "$3" > "$out/$1/$2.m0"
  printf '\x01' | cat - "$3" > "$out/$1/$2.m1"
}

# Generated meshes: an octahedron-like sphere (level 0: 12 vertices) and a small grid.
"$cli" generate sphere --level 0 -o "$work/s.ply" 2>/dev/null
"$cli" generate grid --rings 3 --segments 4 -o "$work/g.ply" 2>/dev/null
for m in s g; do
  "$cli" convert "$work/$m.ply" "$work/${m}_ascii.ply" --ascii 2>/dev/null
  for ext in obj off stl; do "$cli" convert "$work/$m.ply" "$work/$m.$ext" 2>/dev/null; done
  seed ply "${m}_binary" "$work/$m.ply"
  seed ply "${m}_ascii" "$work/${m}_ascii.ply"
  seed obj "$m" "$work/$m.obj"
  seed off "$m" "$work/$m.off"
  seed stl "${m}_binary" "$work/$m.stl"
done

# Hand-written variants: big-endian PLY with extra properties and a quad, OBJ corner forms,
# OFF with colours and comments, ascii STL.
printf 'ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nelement face 1\nproperty list uchar int vertex_indices\nproperty float quality\nend_header\n' > "$work/be.ply"
# Big-endian doubles: 0.0, 1.0 = 3ff0..., 0.5 = 3fe0...; then uchar red = 7.
z='\x00\x00\x00\x00\x00\x00\x00\x00' one='\x3f\xf0\x00\x00\x00\x00\x00\x00' half='\x3f\xe0\x00\x00\x00\x00\x00\x00'
printf "$z$z$half\x07$one$z$half\x07$one$one$half\x07$z$one$half\x07" >> "$work/be.ply"
printf '\x04\x00\x00\x00\x00\x00\x00\x00\x01\x00\x00\x00\x02\x00\x00\x00\x03\x3e\x80\x00\x00' >> "$work/be.ply"
seed ply be "$work/be.ply"
printf 'ply\nformat ascii 1.0\ncomment c\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 2\nproperty list uchar uint vertex_indices\nelement edge 1\nproperty int a\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n0\n' > "$work/a.ply"
seed ply a "$work/a.ply"
# Triangle strips (-1 restarts, a degenerate join, no trailing -1) with vertex attributes, in
# ascii and little endian (floats 0 and 1 are 00000000 and 0000803f).
printf 'ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty float confidence\nproperty float nx\nelement tristrips 1\nproperty list int int vertex_indices\nend_header\n0 0 0 9 0.5 0\n1 0 0 9 0.5 0\n0 1 0 9 0.5 0\n1 1 0 9 0.5 0\n10 0 1 2 3 -1 3 3 2 1 0\n' > "$work/strips.ply"
seed ply strips_ascii "$work/strips.ply"
printf 'ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty ushort quality\nelement tristrips 1\nproperty list int int vertex_indices\nend_header\n' > "$work/strips_le.ply"
o='\x00\x00\x00\x00' l='\x00\x00\x80\x3f' q='\x07\x00'
printf "$o$o$o$q$l$o$o$q$o$l$o$q$l$l$o$q" >> "$work/strips_le.ply"
printf '\x06\x00\x00\x00\x00\x00\x00\x00\x01\x00\x00\x00\x02\x00\x00\x00\xff\xff\xff\xff\x01\x00\x00\x00\x03\x00\x00\x00' >> "$work/strips_le.ply"
seed ply strips_le "$work/strips_le.ply"
# Big endian with ushort indices: the -1 restart is stored as ffff.
printf 'ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement tristrips 1\nproperty list uchar ushort vertex_indices\nend_header\n' > "$work/strips_be.ply"
o='\x00\x00\x00\x00' l='\x3f\x80\x00\x00'
printf "$o$o$o$l$o$o$o$l$o$l$l$o" >> "$work/strips_be.ply"
printf '\x07\x00\x00\x00\x01\x00\x02\xff\xff\x00\x01\x00\x03\x00\x02' >> "$work/strips_be.ply"
seed ply strips_be "$work/strips_be.ply"
printf '# c\nv 0 0 0\nv 1 0 0 1\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\ng x\nf 1/1/1 2/1/1 3/1/1\nf -4//1 -2//1 -1//1\nf 1 2 \\\n 3 4\n' > "$work/c.obj"
seed obj corners "$work/c.obj"
printf 'v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n' > "$work/colours.obj"
seed obj colours "$work/colours.obj"
printf 'COFF\n# comment\n4 2 0\n0 0 0 255 0 0 255\n1 0 0 255 0 0 255\n1 1 0 0 255 0 255\n0 1 0 0 0 255 255\n4 0 1 2 3 1 0 0\n3 0 2 3\n' > "$work/c.off"
seed off coff "$work/c.off"
printf 'STOFF 3 1\n0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 1\n3 0 1 2\n' > "$work/st.off"
seed off stoff "$work/st.off"
printf 'solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n' > "$work/a.stl"
seed stl ascii "$work/a.stl"

# Truncated copies of the bundled meshes (the first 3 KiB: header and a few records).
for f in "$here"/tests/data/*.ply "$here"/tests/data/*.obj "$here"/tests/data/*.off; do
  [ -e "$f" ] || continue
  ext=${f##*.}
  head -c 3072 "$f" > "$work/t.$ext"
  seed "$ext" "trunc_$(basename "$f" ."$ext")" "$work/t.$ext"
done

# Store: a level-1 sphere (42 vertices) ingested, laid end to end.
"$cli" generate sphere --level 1 -o "$work/s1.ply" 2>/dev/null
"$cli" ingest "$work/s1.ply" "$work/store" 2>/dev/null
{
  printf '\x00'
  cat "$work/store"/{header.bin,positions.f32,triangles.u32,vv_offsets.u64,vv.u32,vf_offsets.u64,vf.u32,flags.u8,chunks.bin,original_ids.u32}
} > "$out/store/sphere1"
"$cli" ingest "$work/g.ply" "$work/store_g" 2>/dev/null
{
  printf '\x00'
  cat "$work/store_g"/{header.bin,positions.f32,triangles.u32,vv_offsets.u64,vv.u32,vf_offsets.u64,vf.u32,flags.u8,chunks.bin,original_ids.u32}
} > "$out/store/grid"
echo "make_corpus: $(find "$out" -type f | wc -l) seeds in $out"
