#include "python/src/arrays.h"

#include <algorithm>
#include <cmath>

namespace streamcvd::python {

namespace {

constexpr uint64_t kBlock = uint64_t(1) << 16;  // elements per sink block, as the readers hand them

std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) s += (d ? ", " : "") + std::to_string(a.shape(d));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

// `obj` as a numpy array of the kinds given ("f", "iu"...), else TypeError naming `what`.
py::array numeric_array(py::handle obj, const char* what, const std::string& kinds, const char* expected) {
  if (obj.is_none()) throw py::type_error(std::string(what) + ": expected " + expected + ", got None");
  py::array a;
  try {
    a = py::array::ensure(obj);
  } catch (const py::error_already_set&) {
  }
  if (!a) throw py::type_error(std::string(what) + ": expected " + expected + ", got " + std::string(py::str(obj.get_type())));
  const char kind = a.dtype().kind();
  if (kinds.find(kind) == std::string::npos)
    throw py::type_error(std::string(what) + ": expected " + expected + ", got dtype " + std::string(py::str(a.dtype())));
  return a;
}

// The PLY type a numpy dtype keeps (float64 → double...); float for anything else.
ScalarType type_of_dtype(const py::dtype& d) {
  const char kind = d.kind();
  const auto size = d.itemsize();
  if (kind == 'u') return size == 1 ? ScalarType::U8 : size == 2 ? ScalarType::U16 : ScalarType::U32;
  if (kind == 'i') return size == 1 ? ScalarType::I8 : size == 2 ? ScalarType::I16 : ScalarType::I32;
  if (kind == 'f' && size == 8) return ScalarType::F64;
  return ScalarType::F32;
}

ScalarType parse_type(const std::string& name, const std::string& attribute) {
  for (int t = 0; t <= int(ScalarType::F64); ++t)
    if (name == scalar_type_name(ScalarType(t))) return ScalarType(t);
  throw py::value_error("attribute_types['" + attribute + "']: expected one of char, uchar, short, ushort, int, uint, "
                        "float, double, got '" + name + "'");
}

}  // namespace

TriangleSoupView InputMesh::view() const {
  return {std::span<const float>(points.data(), size_t(points.size())),
          std::span<const uint32_t>(faces.data(), size_t(faces.size()))};
}

void InputMesh::stream(MeshSink& sink, const std::atomic<bool>& cancel) const {
  MeshHeaderInfo header;
  header.format = MeshFormat::Ply;
  header.vertices = vertex_count();
  header.faces = face_count();
  header.vertices_before_triangles = true;
  header.attributes = attributes;
  sink.begin(header);
  const size_t k = attributes.size();
  const TriangleSoupView soup = view();
  for (uint64_t v = 0; v < vertex_count(); v += kBlock) {
    if (cancel.load(std::memory_order_relaxed)) throw Cancelled{};
    const uint64_t n = std::min<uint64_t>(kBlock, vertex_count() - v);
    sink.vertices(soup.positions.subspan(3 * v, 3 * n),
                  k ? std::span<const float>(attribute_values).subspan(k * v, k * n) : std::span<const float>());
  }
  for (uint64_t f = 0; f < face_count(); f += kBlock) {
    if (cancel.load(std::memory_order_relaxed)) throw Cancelled{};
    const uint64_t n = std::min<uint64_t>(kBlock, face_count() - f);
    sink.triangles(soup.triangles.subspan(3 * f, 3 * n));
  }
  ReadStats stats;
  stats.vertices = vertex_count();
  stats.triangles = face_count();
  sink.end(stats);
}

InputMesh input_mesh(py::handle points_obj, py::handle faces_obj, py::handle attributes_obj, py::handle types_obj) {
  InputMesh mesh;
  const py::array points = numeric_array(points_obj, "points", "fiu", "a float array of shape (V, 3)");
  if (points.ndim() != 2 || points.shape(1) != 3)
    throw py::value_error("points: expected shape (V, 3), got " + shape_text(points));
  if (points.shape(0) == 0) throw py::value_error("points: the mesh has no vertex");
  if (points.shape(0) >= py::ssize_t(UINT32_MAX)) throw py::value_error("points: more than 2^32 - 2 vertices");
  mesh.points = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(points);
  const float* p = mesh.points.data();
  for (py::ssize_t i = 0; i < mesh.points.size(); ++i)
    if (!std::isfinite(p[i]))
      throw py::value_error("points: vertex " + std::to_string(i / 3) + " has a non-finite coordinate (" +
                            std::to_string(p[i]) + " as float32)");

  const py::array faces = numeric_array(faces_obj, "faces", "iu", "an integer array of shape (F, 3)");
  if (faces.ndim() != 2 || faces.shape(1) != 3)
    throw py::value_error("faces: expected shape (F, 3), got " + shape_text(faces));
  if (faces.shape(0) == 0) throw py::value_error("faces: the mesh has no face");
  const int64_t V = points.shape(0);
  auto bad_index = [&](py::ssize_t i, int64_t index) {
    return py::value_error("faces: face " + std::to_string(i / 3) + " uses vertex " + std::to_string(index) +
                           (index < 0 ? " (negative)" : ", there are " + std::to_string(V) + " vertices"));
  };
  if (faces.dtype().is(py::dtype::of<uint32_t>()) && (faces.flags() & py::array::c_style)) {
    mesh.faces = py::array_t<uint32_t, py::array::c_style>::ensure(faces);  // the caller's array itself
    const uint32_t* f = mesh.faces.data();
    for (py::ssize_t i = 0; i < mesh.faces.size(); ++i)
      if (int64_t(f[i]) >= V) throw bad_index(i, f[i]);
  } else {
    const auto wide = py::array_t<int64_t, py::array::c_style | py::array::forcecast>::ensure(faces);
    mesh.faces = py::array_t<uint32_t, py::array::c_style>({faces.shape(0), py::ssize_t(3)});
    const int64_t* in = wide.data();
    uint32_t* out = mesh.faces.mutable_data();
    for (py::ssize_t i = 0; i < wide.size(); ++i) {
      if (in[i] < 0 || in[i] >= V) throw bad_index(i, in[i]);
      out[i] = uint32_t(in[i]);
    }
  }

  if (attributes_obj.is_none()) return mesh;
  if (!py::isinstance<py::dict>(attributes_obj))
    throw py::type_error("attributes: expected a dict {name: array of V values}, got " +
                         std::string(py::str(attributes_obj.get_type())));
  const py::dict types = types_obj.is_none() ? py::dict() : py::dict(py::reinterpret_borrow<py::object>(types_obj));
  std::vector<py::array_t<float, py::array::c_style>> columns;
  for (auto [key, value] : py::reinterpret_borrow<py::dict>(attributes_obj)) {
    if (!py::isinstance<py::str>(key)) throw py::type_error("attributes: names must be strings");
    const std::string name = py::str(key);
    if (name.empty() || name.find_first_of(" \t\n") != std::string::npos)
      throw py::value_error("attributes: '" + name + "' is not a property name (empty or with spaces)");
    const std::string what = "attributes['" + name + "']";
    const py::array a = numeric_array(value, what.c_str(), "fiub", "a numeric array of V values");
    if (a.ndim() != 1 || a.shape(0) != V)
      throw py::value_error(what + ": expected shape (" + std::to_string(V) + ",), got " + shape_text(a));
    const ScalarType type = types.contains(key) ? parse_type(py::str(types[key]), name) : type_of_dtype(a.dtype());
    mesh.attributes.push_back({name, type});
    columns.push_back(py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(a));
  }
  const size_t k = columns.size();
  mesh.attribute_values.resize(size_t(V) * k);
  for (size_t c = 0; c < k; ++c) {
    const float* col = columns[c].data();
    for (int64_t v = 0; v < V; ++v) {
      if (!std::isfinite(col[v]))
        throw py::value_error("attributes['" + mesh.attributes[c].name + "']: vertex " + std::to_string(v) +
                              " has a non-finite value");
      mesh.attribute_values[size_t(v) * k + c] = col[v];
    }
  }
  return mesh;
}

py::dict attribute_columns(const py::array_t<float>& rows, const std::vector<VertexAttribute>& attributes) {
  py::dict out;
  const size_t k = attributes.size();
  for (size_t c = 0; c < k; ++c) {
    // A strided view of column c: the rows array stays alive as the view's base.
    py::array_t<float> column({rows.shape(0)}, {py::ssize_t(k * sizeof(float))}, rows.data() + c, rows);
    py::detail::array_proxy(column.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
    out[py::str(attributes[c].name)] = column;
  }
  return out;
}

py::dict attribute_types(const std::vector<VertexAttribute>& attributes) {
  py::dict out;
  for (const VertexAttribute& a : attributes) out[py::str(a.name)] = py::str(scalar_type_name(a.type));
  return out;
}

py::object to_python(const nlohmann::json& j) {
  switch (j.type()) {
    case nlohmann::json::value_t::null: return py::none();
    case nlohmann::json::value_t::boolean: return py::bool_(j.get<bool>());
    case nlohmann::json::value_t::number_integer: return py::int_(j.get<int64_t>());
    case nlohmann::json::value_t::number_unsigned: return py::int_(j.get<uint64_t>());
    case nlohmann::json::value_t::number_float: {
      const double x = j.get<double>();
      return std::isfinite(x) ? py::object(py::float_(x)) : py::object(py::none());  // JSON text writes null
    }
    case nlohmann::json::value_t::string: return py::str(j.get_ref<const std::string&>());
    case nlohmann::json::value_t::array: {
      py::list list;
      for (const auto& item : j) list.append(to_python(item));
      return list;
    }
    case nlohmann::json::value_t::object: {
      py::dict dict;
      for (const auto& [key, value] : j.items()) dict[py::str(key)] = to_python(value);
      return dict;
    }
    default: return py::none();  // binary and discarded values never occur in a record
  }
}

}  // namespace streamcvd::python
