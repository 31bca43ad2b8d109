// read_mesh_stream: format from the extension (after stripping ".zst") or, failing that, from
// the first bytes of the (decompressed) content; then the per-format producer. The in-RAM
// collectors (read_mesh...) are in mesh_collect.cpp.
#include <algorithm>
#include <cctype>
#include <cstring>
#include <string>
#include <string_view>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/block_emitter.h"
#include "streamcvd/streaming/io/input_stream.h"
#include "streamcvd/streaming/io/mesh_reader.h"

namespace streamcvd {

const char* scalar_type_name(ScalarType type) {
  constexpr const char* kNames[] = {"char", "uchar", "short", "ushort", "int", "uint", "float", "double"};
  return kNames[static_cast<int>(type)];
}

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

void read_mesh_stream(const std::string& path, MeshSink& sink, const ReadOptions& options) {
  InputStream in(path);
  MeshFormat format;
  // A pipe has no extension to go by ("-"): the content decides.
  if (!format_from_extension(path, format)) format = sniff_format(in);
  BlockEmitter out(in, sink, options);
  out.header().format = format;
  switch (format) {
    case MeshFormat::Ply: stream_ply(in, out); break;
    case MeshFormat::Obj: stream_obj(in, out); break;
    case MeshFormat::Off: stream_off(in, out); break;
    case MeshFormat::Stl: stream_stl(in, out); break;
  }
  out.finish();
}

}  // namespace streamcvd
