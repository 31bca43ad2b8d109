// numpy arrays in and out of the library for the Python module: checked input meshes viewed as
// float32 / uint32 arrays (copied only when the dtype or layout differs), output vectors handed
// over to numpy without a copy, and JSON records as Python objects.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <atomic>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/mesh_view.h"
#include "streamcvd/streaming/io/mesh_reader.h"

namespace streamcvd::python {

namespace py = pybind11;

/// A mesh given as numpy arrays, checked: points (V, 3) finite floats, faces (F, 3) integers in
/// [0, V), attributes a {name: (V,) array} dict. Holds float32 / uint32 C-contiguous arrays
/// (the caller's own when they already are, else converted copies).
struct InputMesh {
  py::array_t<float, py::array::c_style> points;
  py::array_t<uint32_t, py::array::c_style> faces;
  std::vector<VertexAttribute> attributes;  ///< names and types (from the dtypes or the given types)
  std::vector<float> attribute_values;      ///< attributes.size() floats per vertex, row-major

  uint32_t vertex_count() const { return uint32_t(points.shape(0)); }
  uint64_t face_count() const { return uint64_t(faces.shape(0)); }
  /// The arrays as the library's soup (valid while this object lives).
  TriangleSoupView view() const;
  VertexAttributeRows attribute_rows() const { return {attributes, attribute_values}; }
  /// Streams the mesh into `sink` as a reader would (header, vertex blocks, triangle blocks, end):
  /// streaming/store/store_build.h's stream_soup with the attribute rows, throwing `Cancelled` between
  /// blocks once `cancel` is set. Without the GIL.
  void stream(MeshSink& sink, const std::atomic<bool>& cancel) const;
};

/// Thrown inside a job whose caller was interrupted (Ctrl-C): unwinds it.
struct Cancelled {};

/// Checks and converts `points`, `faces` and `attributes` (None or a dict); `types` (None or a
/// {name: "uchar" | "float" | ...} dict) overrides the PLY types taken from the dtypes.
/// Throws TypeError (not an array, wrong dtype) or ValueError (shape, NaN/Inf, index ≥ V, no face).
InputMesh input_mesh(py::handle points, py::handle faces, py::handle attributes = py::none(),
                     py::handle types = py::none());

/// `values` as a (rows, cols) numpy array that owns them: no copy, the vector's buffer is handed
/// over (freed when the array and its views are gone).
template <class T>
py::array_t<T> hand_over(std::vector<T>&& values, size_t rows, size_t cols) {
  auto* owned = new std::vector<T>(std::move(values));
  py::capsule owner(owned, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>({rows, cols}, {cols * sizeof(T), sizeof(T)}, owned->data(), owner);
}

/// {name: (V,) float32 column view} of a (V, K) array of attribute rows (no copy), and the
/// matching {name: PLY type} dict.
py::dict attribute_columns(const py::array_t<float>& rows, const std::vector<VertexAttribute>& attributes);
py::dict attribute_types(const std::vector<VertexAttribute>& attributes);

/// A JSON record as Python objects (dict, list, int, float, str, bool, None), equal to what
/// json.loads gives for its text (non-finite numbers, written as null, are None).
py::object to_python(const nlohmann::json& j);

}  // namespace streamcvd::python
