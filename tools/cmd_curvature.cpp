// `curvature`: principal curvatures and directions of every vertex (core/fields/curvature.h), written
// as a PLY whose vertices carry x y z k1 k2 d1x d1y d1z d2x d2y d2z, followed by the faces.
// Vertices and faces are in store order (Hilbert-sorted when the input is a mesh file).
#include <tbb/global_control.h>

#include <bit>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <memory>
#include <string>

#include "streamcvd/core/fields/curvature.h"
#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/io/output_file.h"
#include "streamcvd/streaming/store/store.h"
#include "tools/commands.h"
#include "tools/job_options.h"

namespace streamcvd::cli {
namespace {

static_assert(std::endian::native == std::endian::little, "the binary PLY below is written as-is");

constexpr size_t kFloatsPerVertex = 11;                  // x y z k1 k2 d1xyz d2xyz
constexpr size_t kAsciiVertexMax = kFloatsPerVertex * 16;  // "-1.1754944e-38 " is 15 characters
constexpr size_t kAsciiFaceMax = 2 + 3 * 11 + 1;         // "3" + " 4294967295" ×3 + newline

void vertex_record(const MeshView& m, const Curvature& c, uint32_t v, float out[kFloatsPerVertex]) {
  for (int j = 0; j < 3; ++j) {
    out[j] = m.positions[3 * size_t(v) + j];
    out[5 + j] = c.d1[3 * size_t(v) + j];
    out[8 + j] = c.d2[3 * size_t(v) + j];
  }
  out[3] = c.k1[v];
  out[4] = c.k2[v];
}

// Streams one record per index through prepare()/advance(), at most kMaxPrepare bytes at a time.
template <class Format>
void write_records(AtomicOutputFile& out, uint64_t count, size_t max_bytes, const Format& format) {
  const uint64_t per_prepare = AtomicOutputFile::kMaxPrepare / max_bytes;
  for (uint64_t i = 0; i < count;) {
    const uint64_t end = std::min(count, i + per_prepare);
    char* const begin = out.prepare(size_t(end - i) * max_bytes);
    char* p = begin;
    for (; i < end; ++i) p = format(p, i);
    out.advance(size_t(p - begin));
  }
}

void write_curvature_ply(const std::string& path, const MeshView& m, const Curvature& c, bool ascii, int rings) {
  AtomicOutputFile out(path, has_zst_extension(path));
  std::string header = std::string("ply\nformat ") + (ascii ? "ascii" : "binary_little_endian") + " 1.0\n";
  header += "comment streamcvd curvature: degree-2 jet over the " + std::to_string(rings) +
            "-ring (Cazals & Pouget 2005); k1 >= k2 in 1/length, > 0 where convex w.r.t. face orientation; "
            "d1, d2 unit principal directions\n";
  header += "element vertex " + std::to_string(m.vertex_count()) + "\n";
  for (const char* p : {"x", "y", "z", "k1", "k2", "d1x", "d1y", "d1z", "d2x", "d2y", "d2z"})
    header += std::string("property float ") + p + "\n";
  header += "element face " + std::to_string(m.face_count()) + "\nproperty list uchar uint vertex_indices\nend_header\n";
  out.write(header);
  const uint32_t* tri = m.triangles.data();
  if (ascii) {
    write_records(out, m.vertex_count(), kAsciiVertexMax, [&](char* p, uint64_t v) {
      float rec[kFloatsPerVertex];
      vertex_record(m, c, uint32_t(v), rec);
      for (size_t j = 0; j < kFloatsPerVertex; ++j) {
        p = std::to_chars(p, p + 15, rec[j]).ptr;  // shortest form that reads back bit-exact
        *p++ = j + 1 < kFloatsPerVertex ? ' ' : '\n';
      }
      return p;
    });
    write_records(out, m.face_count(), kAsciiFaceMax, [&](char* p, uint64_t f) {
      *p++ = '3';
      for (int j = 0; j < 3; ++j) {
        *p++ = ' ';
        p = std::to_chars(p, p + 10, tri[3 * f + j]).ptr;
      }
      *p++ = '\n';
      return p;
    });
  } else {
    write_records(out, m.vertex_count(), sizeof(float) * kFloatsPerVertex, [&](char* p, uint64_t v) {
      float rec[kFloatsPerVertex];
      vertex_record(m, c, uint32_t(v), rec);
      std::memcpy(p, rec, sizeof rec);
      return p + sizeof rec;
    });
    write_records(out, m.face_count(), 13, [&](char* p, uint64_t f) {
      *p = 3;
      std::memcpy(p + 1, tri + 3 * f, 12);
      return p + 13;
    });
  }
  out.commit();
}

}  // namespace

void add_curvature_command(CLI::App& app) {
  struct Args {
    std::string input, output;
    bool ascii = false;
    int threads = 0;
    CurvatureOptions options;
    JobOptions job;
  };
  auto args = std::make_shared<Args>();
  auto* cmd = app.add_subcommand("curvature", "Principal curvatures and directions per vertex (jet fitting) to a PLY");
  cmd->add_option("input", args->input, "Mesh file or store directory")->required();
  cmd->add_option("-o,--output", args->output, "Output PLY (.ply or .ply.zst)")->required();
  cmd->add_flag("--ascii", args->ascii, "Write an ascii PLY instead of binary little-endian");
  cmd->add_option("--rings", args->options.rings,
                  "Neighbourhood of the fit, in edges (1-10); noisy scans want more (8 keeps k1, k2 within 10% "
                  "at 1% noise)")
      ->capture_default_str()
      ->check(CLI::Range(1, 10));
  cmd->add_option("--min-neighbours", args->options.min_neighbours,
                  "Grow the ring (up to max(5, --rings)) while fewer neighbours, then give up (k = 0)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000));
  cmd->add_option("--threads", args->threads, "Worker threads (0: every core)")
      ->capture_default_str()
      ->check(CLI::Range(0, 4096));
  add_job_options(cmd, args->job, /*with_threads=*/false);
  cmd->callback([args] {
    if (format_from_path(args->output) != MeshFormat::Ply)
      throw InputError(error_at(args->output, "curvature: the output must be a .ply (or .ply.zst) file"));
    std::unique_ptr<tbb::global_control> limit;
    if (args->threads > 0)
      limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, args->threads);
    const double t0 = now_seconds();
    StoreBuildOptions store_options;
    store_options.memory_limit = memory_limit(args->job);
    store_options.work_directory = args->job.work_dir;
    const MeshStore store = streamcvd::load_mesh_or_store(args->input, store_options);
    const MeshView view = store.view();
    const double t1 = now_seconds();
    const std::clock_t cpu0 = std::clock();
    const Curvature c = compute_curvature(view, args->options);
    const double cpu = double(std::clock() - cpu0) / CLOCKS_PER_SEC;
    const double t2 = now_seconds();
    write_curvature_ply(args->output, view, c, args->ascii, args->options.rings);
    const double t3 = now_seconds();
    std::fprintf(stderr,
                 "curvature: %s -> %s: %u vertices, %llu fallbacks (k = 0); load %.2f s, curvature %.2f s "
                 "(CPU %.2f s), write %.2f s; peak RSS %.0f MB\n",
                 args->input.c_str(), args->output.c_str(), view.vertex_count(),
                 (unsigned long long)c.fallback_count, t1 - t0, t2 - t1, cpu, t3 - t2,
                 double(peak_rss_bytes()) / 1e6);
  });
}

}  // namespace streamcvd::cli
