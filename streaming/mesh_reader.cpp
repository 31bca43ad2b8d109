// Generic read entry points: format from the extension (after stripping ".zst") or, failing
// that, from the first bytes of the (decompressed) content; then the per-format reader and a
// validation pass over the soup.
#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <string>
#include <string_view>

#include "core/errors.h"
#include "streaming/input_stream.h"
#include "streaming/mesh_io.h"

namespace streamcvd {

namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

bool ends_with(const std::string& s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// The extension's format, or false when the extension names none.
bool format_from_extension(const std::string& path, MeshFormat& out) {
  std::string name = lower(path);
  if (ends_with(name, ".zst")) name.resize(name.size() - 4);
  constexpr std::pair<std::string_view, MeshFormat> kExtensions[] = {
      {".ply", MeshFormat::Ply}, {".obj", MeshFormat::Obj}, {".off", MeshFormat::Off}, {".stl", MeshFormat::Stl}};
  for (const auto& [ext, format] : kExtensions)
    if (ends_with(name, ext)) {
      out = format;
      return true;
    }
  return false;
}

// "OFF", "COFF", "NOFF", "CNOFF", "STOFF", "4OFF", "nOFF", "STCN4nOFF"...: an optional prefix of
// the letters S T C N 4 n (in that order), then "OFF".
bool is_off_keyword(std::string_view word) {
  if (word.size() < 3 || word.substr(word.size() - 3) != "OFF") return false;
  std::string_view prefix = word.substr(0, word.size() - 3);
  if (prefix.starts_with("ST")) prefix.remove_prefix(2);
  for (char c : {'C', 'N', '4', 'n'})
    if (!prefix.empty() && prefix.front() == c) prefix.remove_prefix(1);
  return prefix.empty();
}

// Sniffs the format from up to 4 KiB of content without consuming it.
MeshFormat sniff_format(InputStream& in) {
  std::span<const char> head = in.fill(4096);
  std::string_view text(head.data(), std::min<size_t>(head.size(), 4096));
  if (text.size() >= 4 && text.starts_with("ply") && (text[3] == '\n' || text[3] == '\r')) return MeshFormat::Ply;
  // Binary STL: 80-byte header, uint32 triangle count, 50 bytes per triangle. The size check is
  // exact, so it comes before the text tests (the 80-byte header may hold any text).
  if (!in.compressed() && in.file_size() >= 84 && text.size() >= 84) {
    uint32_t n;
    std::memcpy(&n, text.data() + 80, 4);  // little endian on every supported host
    if (84 + 50 * uint64_t(n) == in.file_size()) return MeshFormat::Stl;
  }
  // First word that is not inside a '#' comment line.
  size_t i = 0;
  for (;;) {
    while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
    if (i < text.size() && text[i] == '#') {
      while (i < text.size() && text[i] != '\n' && text[i] != '\r') ++i;
      continue;
    }
    break;
  }
  size_t j = i;
  while (j < text.size() && !std::isspace(static_cast<unsigned char>(text[j]))) ++j;
  std::string_view word = text.substr(i, j - i);
  if (is_off_keyword(word)) return MeshFormat::Off;
  if (text.starts_with("solid")) return MeshFormat::Stl;
  // Only binary STL has no magic: control bytes mean binary STL (compressed, so no size check).
  for (char c : text.substr(0, 84))
    if (static_cast<unsigned char>(c) < 0x20 && c != '\n' && c != '\r' && c != '\t' && c != '\f' && c != '\v')
      return MeshFormat::Stl;
  return MeshFormat::Obj;
}

}  // namespace

MeshFormat format_from_path(const std::string& path) {
  MeshFormat format;
  if (!format_from_extension(path, format))
    throw InputError(error_at(path, "unknown mesh file extension (expected .ply, .obj, .off or .stl, optionally + .zst)"));
  return format;
}

bool has_zst_extension(const std::string& path) { return ends_with(lower(path), ".zst"); }

MeshBuffers read_mesh(const std::string& path) {
  InputStream in(path);
  MeshFormat format;
  if (!format_from_extension(path, format)) format = sniff_format(in);
  MeshBuffers mesh;
  switch (format) {
    case MeshFormat::Ply: mesh = read_ply(in); break;
    case MeshFormat::Obj: mesh = read_obj(in); break;
    case MeshFormat::Off: mesh = read_off(in); break;
    case MeshFormat::Stl: mesh = read_stl(in); break;
  }
  validate_soup(path, mesh);
  return mesh;
}

void validate_soup(const std::string& path, const MeshBuffers& mesh) {
  if (mesh.positions.size() % 3 != 0)
    throw InputError(error_at(path, "position array length " + std::to_string(mesh.positions.size()) + " is not a multiple of 3"));
  if (mesh.triangles.size() % 3 != 0)
    throw InputError(error_at(path, "index array length " + std::to_string(mesh.triangles.size()) + " is not a multiple of 3"));
  const uint64_t v = mesh.positions.size() / 3;
  if (v == 0) throw InputError(error_at(path, "no vertices"));
  if (v > 0xFFFFFFFFull) throw InputError(error_at(path, "more than 2^32-1 vertices (" + std::to_string(v) + ")"));
  // Cheap whole-array tests first (they vectorize); the slow loops only run to name the culprit.
  uint32_t non_finite = 0;  // exponent bits all set: inf or nan (std::isfinite does not vectorize)
  for (float x : mesh.positions) non_finite |= (std::bit_cast<uint32_t>(x) & 0x7f800000u) == 0x7f800000u;
  if (non_finite)
    for (size_t i = 0; i < mesh.positions.size(); ++i)
      if (!std::isfinite(mesh.positions[i]))
        throw InputError(error_at(path, "vertex " + std::to_string(i / 3) + " has a non-finite coordinate (" +
                                            std::to_string(mesh.positions[i]) + ")"));
  uint32_t max_index = 0;
  for (uint32_t t : mesh.triangles) max_index = t > max_index ? t : max_index;
  if (!mesh.triangles.empty() && max_index >= v)
    for (size_t i = 0; i < mesh.triangles.size(); ++i)
      if (mesh.triangles[i] >= v)
        throw InputError(error_at(path, "face " + std::to_string(i / 3) + " uses vertex " +
                                            std::to_string(mesh.triangles[i]) + " of " + std::to_string(v)));
}

}  // namespace streamcvd
