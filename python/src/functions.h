// The functions of the Python module `streamcvd` (bound with their docstrings in module.cpp):
// each converts and checks its arguments, runs the library's own entry points (those the CLI
// runs, so the outputs are the same bytes) off the GIL, and returns numpy arrays and dicts.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <string>
#include <vector>

#include "streamcvd/streaming/io/mesh_reader.h"
#include "streamcvd/streaming/remesh_pipeline.h"

namespace streamcvd::python {

namespace py = pybind11;

/// A mesh in numpy arrays: points (V, 3) float32, faces (F, 3) uint32, attributes {name: (V,)
/// float32 column}, owned by the library's buffers handed over (no copy).
struct Mesh {
  py::array points, faces;
  py::object attribute_rows = py::none();  ///< (V, K) float32 whose columns `attributes` views
  std::vector<VertexAttribute> attribute_list;
  py::dict attributes, attribute_types;
  std::string comment;  ///< written into the header by write() (a remesh output: the CLI's)

  /// Writes the mesh to `path` (format from the extension), as `streamcvd.write` does.
  void write(const std::string& path, bool ascii) const;
};

/// What remesh() returns: the output mesh and the report dict of `streamcvd remesh --report`.
struct Result : Mesh {
  py::object report;
};

/// The library's defaults (RemeshOptions{}), which are the CLI's too.
inline const RemeshOptions kRemeshDefaults;

/// The options every remesh call takes (keyword arguments, defaults from kRemeshDefaults).
struct RemeshArgs {
  py::object n;
  std::string metric = metric_name(kRemeshDefaults.clustering.metric);
  double gradation = kRemeshDefaults.gradation;
  uint64_t seed = kRemeshDefaults.seed;
  int threads = int(kRemeshDefaults.clustering.loops.threads);
  bool deterministic = kRemeshDefaults.clustering.loops.deterministic;
  std::string small_components = small_components_name(kRemeshDefaults.small_components);
  bool boundary_strips = kRemeshDefaults.boundary_strips;
  py::object memory = py::none();      ///< None, bytes, or "512M"
  py::object attributes = py::none();  ///< remesh(): {name: array}; remesh_file(): "all", "none" or names
  std::string algorithm = algorithm_name(kRemeshDefaults.clustering.algorithm);
  int curvature_rings = kRemeshDefaults.curvature_rings;
  double qem_threshold = kRemeshDefaults.clustering.qem_threshold;
  py::object subdivide = py::str("auto");
  bool project = kRemeshDefaults.project_to_surface, optimize = kRemeshDefaults.optimize_quality;
  py::object work_dir = py::none();
  py::object progress = py::none();  ///< None or a callable taking one dict per progress report
};

Result remesh_arrays(py::handle points, py::handle faces, const RemeshArgs& args);
Result remesh_file(const std::string& input, const std::string& output, const RemeshArgs& args, py::object report,
                   bool keep_work, bool ascii);
Mesh read(const std::string& path, py::handle attributes);
void write(const std::string& path, py::handle points, py::handle faces, py::handle attributes, py::handle types,
           bool ascii, const std::string& comment);
py::object ingest(const std::string& input, const std::string& store, py::object memory, py::object work_dir,
                  int threads, uint64_t faces_per_chunk, py::object progress);
py::object quality(py::handle points, py::handle faces);
py::object info(py::handle mesh, py::handle faces, py::object memory, py::object work_dir, int threads);
py::object distance(py::handle a, py::handle b, uint64_t samples, uint64_t seed, int threads);

/// `path` as given: a str or an os.PathLike (TypeError otherwise).
std::string path_text(py::handle path);

}  // namespace streamcvd::python
