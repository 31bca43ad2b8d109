// The Python module streamcvd._core (re-exported by the package streamcvd): the bindings and
// their docstrings. The functions are in functions.cpp, the array conversions in arrays.cpp.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <tuple>

#include "streamcvd/core/mesh/errors.h"
#include "python/src/functions.h"

namespace py = pybind11;
using namespace streamcvd::python;

namespace {

// The keyword arguments remesh() and remesh_file() share, with the CLI's defaults.
auto remesh_keywords() {
  const RemeshArgs d;
  return std::make_tuple(py::kw_only(), py::arg("metric") = d.metric, py::arg("gradation") = d.gradation,
                         py::arg("seed") = d.seed, py::arg("threads") = d.threads,
                         py::arg("deterministic") = d.deterministic, py::arg("small_components") = d.small_components,
                         py::arg("boundary_strips") = d.boundary_strips, py::arg("memory") = py::none(),
                         py::arg("attributes") = py::none(), py::arg("algorithm") = d.algorithm,
                         py::arg("curvature_rings") = d.curvature_rings, py::arg("qem_threshold") = d.qem_threshold,
                         py::arg("subdivide") = "auto", py::arg("project") = d.project, py::arg("optimize") = d.optimize,
                         py::arg("work_dir") = py::none(), py::arg("progress") = py::none());
}

#define STREAMCVD_REMESH_PARAMS                                                                                      \
  py::object n, const std::string &metric, double gradation, uint64_t seed, int threads, bool deterministic,        \
      const std::string &small_components, bool boundary_strips, py::object memory, py::object attributes,          \
      const std::string &algorithm, int curvature_rings, double qem_threshold, py::object subdivide, bool project, \
      bool optimize, py::object work_dir, py::object progress
#define STREAMCVD_REMESH_ARGS                                                                                         \
  RemeshArgs {                                                                                                        \
    n, metric, gradation, seed, threads, deterministic, small_components, boundary_strips, memory, attributes,        \
        algorithm, curvature_rings, qem_threshold, subdivide, project, optimize, work_dir, progress                   \
  }

constexpr const char* kRemeshOptionsDoc = R"(
    n: output vertices, exactly (boundary-strip vertices included; at least 4). Not met only when
        the strips alone need n/2 or more: report["checks"]["vertex_count_note"] then says why.
    metric: "I" isotropic, "IQ" (default) isotropic with QEM vertex placement, "A" anisotropic
        (curvature tensors), "AQ" anisotropic with QEM placement.
    gradation: curvature-adapted density γ of eq. 20 (0 = uniform, range -8 to 8).
    seed: seed of the initial sampling (same seed and threads=1 or deterministic=True: same output).
    threads: worker threads, 0 (default) = all cores. With more than one thread two runs may differ
        slightly unless deterministic=True; threads=1 is the serial, reproducible clustering.
    deterministic: parallel clustering whose output is the same for every thread count.
    small_components: "keep" (default: components too small for the budget get the few clusters
        they need) or "drop".
    boundary_strips: triangle strips along the input's boundaries (paper §VI-D).
    memory: what the job may use: None (default: 3/4 of the cgroup limit, else 1/2 of the available
        memory), bytes, or a size such as "512M". Changes what stays in RAM, never the output.
    algorithm: "cvd" (Algorithm 1) or "lloyd" (the §VII baseline, metrics I and IQ).
    curvature_rings: rings of the curvature fit for gradation and A/AQ (1-10, default 3).
    qem_threshold: IQ/AQ relative eigenvalue cut of the vertex placement (0-1, default 0.01).
    subdivide: "auto" (default: 1->4 subdivision when fewer than ~10 input vertices per
        cluster), "none", or a level 0-6.
    project: output vertices on the input surface (False: raw cluster centroids).
    optimize: the quality post-pass (flips, relaxation, strip shaping).
    work_dir: folder of the work files (default: TMPDIR), anonymous and removed whatever happens.
    progress: None or a callable given one dict per report, at most ~10 a second per stage and
        once when a stage ends: {"stage": "read" | "clustering" | ..., "done", "total" (0 if
        unknown), "unit", "round", "fraction" (0-1, None if unknown), "finished"}. It runs on
        a worker thread holding the GIL; an exception it raises stops the job and is raised.
)";

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() = "streamcvd: discrete centroidal Voronoi remeshing of large triangle meshes (Valette, Chassery & Prost 2008)";
  m.attr("__version__") = STREAMCVD_VERSION;
  py::register_exception<streamcvd::InputError>(m, "InputError", PyExc_ValueError);
  py::register_exception<streamcvd::OutputError>(m, "OutputError", PyExc_OSError);

  py::class_<Mesh>(m, "Mesh", R"(A triangle mesh in numpy arrays.

    points: (V, 3) float32 vertex positions.
    faces: (F, 3) uint32 vertex indices, counter-clockwise seen from outside.
    attributes: {name: (V,) float32} per-vertex values (colours "red", "green", "blue", scalars
        such as "confidence"), read-only views of one (V, K) buffer.
    attribute_types: {name: PLY type} ("uchar", "float"...), the types write() uses.)")
      .def_readonly("points", &Mesh::points)
      .def_readonly("faces", &Mesh::faces)
      .def_readonly("attributes", &Mesh::attributes)
      .def_readonly("attribute_types", &Mesh::attribute_types)
      .def("write", [](const Mesh& mesh, py::handle path, bool ascii) { mesh.write(path_text(path), ascii); },
           py::arg("path"), py::kw_only(), py::arg("ascii") = false,
           R"(Writes the mesh to `path`, format from the extension (.ply, .obj, .off, .stl, each
    optionally + .zst), atomically (a failure leaves no file). A remesh result is written with
    the header comment of the CLI, so its bytes are those of `streamcvd remesh -o path`.
    ascii: ascii PLY instead of binary little endian.)")
      .def("__repr__", [](const Mesh& mesh) {
        return "<streamcvd.Mesh " + std::to_string(mesh.points.shape(0)) + " vertices, " +
               std::to_string(mesh.faces.shape(0)) + " faces>";
      });
  py::class_<Result, Mesh>(m, "Result", R"(What remesh() and remesh_file() return: the output Mesh and
    report, the dict of `streamcvd remesh --report` (times in seconds, memory in bytes).)")
      .def_readonly("report", &Result::report)
      .def("__repr__", [](const Result& r) {
        return "<streamcvd.Result " + std::to_string(r.points.shape(0)) + " vertices, " +
               std::to_string(r.faces.shape(0)) + " faces>";
      });

  std::apply(
      [&](auto... keywords) {
        m.def(
            "remesh",
            [](py::object points, py::object faces, STREAMCVD_REMESH_PARAMS) {
              return remesh_arrays(points, faces, STREAMCVD_REMESH_ARGS);
            },
            py::arg("points"), py::arg("faces"), py::arg("n"), keywords...,
            (std::string(R"(Remeshes a triangle mesh given as arrays to n vertices; returns a Result.

    The engine of `streamcvd remesh` (same output for the same seed and threads=1). The GIL is
    released; Ctrl-C stops the job and raises KeyboardInterrupt.

    points: (V, 3) float32 or float64 array (float64 is rounded to float32, as files are read).
    faces: (F, 3) integer array of vertex indices in [0, V).
    attributes: None or {name: (V,) array} of per-vertex values carried to the output as
        area-weighted cluster means (Result.attributes); PLY types from the dtypes.)") +
             kRemeshOptionsDoc +
             R"(
    Raises TypeError / ValueError for bad arguments (shape, dtype, NaN, index >= V, n < 4) and
    streamcvd.InputError (a ValueError) when the library refuses the input.)")
                .c_str());
        m.def(
            "remesh_file",
            [](py::object input, py::object output, STREAMCVD_REMESH_PARAMS, py::object report, bool keep_work,
               bool ascii) {
              return remesh_file(path_text(input), path_text(output), STREAMCVD_REMESH_ARGS, report, keep_work, ascii);
            },
            py::arg("input"), py::arg("output"), py::arg("n"), keywords..., py::arg("report") = py::none(),
            py::arg("keep_work") = false, py::arg("ascii") = false,
            (std::string(R"(Remeshes a mesh file or store directory into the file `output`, out of core, in the
    memory given; returns the Result (its arrays hold the output mesh).

    `streamcvd remesh input -o output -n n` in-process: the same output bytes and report.
    The output is written atomically: an error or Ctrl-C (KeyboardInterrupt) leaves no file.

    input: mesh file (PLY, OBJ, OFF, STL, optionally .zst) or store directory (see ingest()).
    output: .ply (binary unless ascii=True), .obj, .off or .stl, optionally + .zst.
    attributes: which vertex attributes to carry: None or "all" (default), "none", or a list of
        names (an unknown name raises InputError listing those the input has).)") +
             kRemeshOptionsDoc +
             R"(    report: also write the report as JSON to this path.
    keep_work: keep the store built from a file input in the work folder (<input>.store).
    Raises as remesh(), and streamcvd.OutputError (an OSError) when a file cannot be written.)")
                .c_str());
      },
      remesh_keywords());

  m.def(
      "read", [](py::object path, py::object attributes) { return read(path_text(path), attributes); },
      py::arg("path"), py::kw_only(), py::arg("attributes") = "all",
      R"(Reads a mesh file (PLY, OBJ, OFF, STL, optionally .zst) into a Mesh, in RAM.

    attributes: vertex attributes to keep: "all" (default), "none" or a list of names.
    Raises streamcvd.InputError naming the file and the line or byte of a problem.)");
  m.def(
      "write",
      [](py::object path, py::object points, py::object faces, py::object attributes, py::object types, bool ascii,
         const std::string& comment) { write(path_text(path), points, faces, attributes, types, ascii, comment); },
      py::arg("path"), py::arg("points"), py::arg("faces"), py::arg("attributes") = py::none(), py::kw_only(),
      py::arg("attribute_types") = py::none(), py::arg("ascii") = false, py::arg("comment") = "",
      R"(Writes points (V, 3) and faces (F, 3) to `path`, format from the extension, atomically.

    attributes: None or {name: (V,) array}: PLY vertex properties (OBJ keeps red, green, blue;
        OFF and STL none), typed from the dtypes (uint8 -> uchar, float32 -> float...) unless
        attribute_types={name: "uchar" | "float" | ...} says otherwise.
    comment: a header comment (PLY, OBJ, OFF).)");
  m.def(
      "ingest",
      [](py::object input, py::object store, py::object memory, py::object work_dir, int threads,
         uint64_t faces_per_chunk, py::object progress) {
        return ingest(path_text(input), path_text(store), memory, work_dir, threads, faces_per_chunk, progress);
      },
      py::arg("input"), py::arg("store"), py::kw_only(), py::arg("memory") = py::none(),
      py::arg("work_dir") = py::none(), py::arg("threads") = 0, py::arg("faces_per_chunk") = uint64_t(1) << 20,
      py::arg("progress") = py::none(),
      R"(Builds the compact store of a mesh file in the directory `store`, in bounded memory (memory=
    and progress= as in remesh()); returns the dict of `streamcvd ingest --json` (bytes, counts,
    seconds).)");
  m.def("quality", &quality, py::arg("points"), py::arg("faces") = py::none(),
        R"(Triangle quality of a mesh: the dict of `streamcvd quality --json` (without "file").

    Q = 6/sqrt(3) * area / (half-perimeter * longest edge), 1 for an equilateral triangle:
    q_min, q_avg, angle statistics in degrees, percent_angles_below_30, percent_valence6,
    edge_length_mean (input units) and edge_length_cv, histograms.
    points: (V, 3) array with faces (F, 3), or a Mesh / Result (faces omitted).)");
  m.def(
      "info",
      [](py::object mesh, py::object faces, py::object memory, py::object work_dir, int threads) {
        return info(mesh, faces, memory, work_dir, threads);
      },
      py::arg("mesh"), py::arg("faces") = py::none(), py::kw_only(), py::arg("memory") = py::none(),
      py::arg("work_dir") = py::none(), py::arg("threads") = 0,
      R"(Counts, bounding box and topology (boundary loops, non-manifold elements, components, Euler
    characteristic, genus) of a mesh as read, and what the topology cleaning does: the dict of
    `streamcvd info --json`. mesh: a path (file or store directory), a Mesh, or points with faces.)");
  m.def("distance", &distance, py::arg("a"), py::arg("b"), py::kw_only(), py::arg("samples") = uint64_t(1'000'000),
        py::arg("seed") = uint64_t(1), py::arg("threads") = 0,
        R"(Two-sided Metro distance between meshes a (the reference) and b, each a Mesh, a
    (points, faces) tuple or a path: the dict of `streamcvd distance --json`'s figures (max, mean,
    rms per side in input units, *_relative to a's bounding-box diagonal, hausdorff).

    samples: random face samples per side, added to the vertices (at most 100,000,000).)");
}
