// The few exception types streamcvd throws. The CLI maps them to exit codes:
// InputError → 2 (bad input or usage), OutputError → 3 (cannot write), CheckFailed → 4 (output
// written, a guarantee failed), anything else → 1.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

namespace streamcvd {

/// Invalid input: a malformed, truncated or unsupported file, or impossible parameters.
/// what() is one line: "<file>: line 12: <problem>" or "<file>: byte 4096: <problem>".
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// An output could not be written (missing folder, permission, disk full).
class OutputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A job whose output was written but fails one of its guarantees (non-manifold, degenerate,
/// components or genus changed...): exit code 4, the output and report left for inspection.
class CheckFailed : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// "<file>: <problem>"
inline std::string error_at(const std::string& file, const std::string& problem) {
  return file + ": " + problem;
}
/// "<file>: line N: <problem>"
inline std::string error_at_line(const std::string& file, uint64_t line, const std::string& problem) {
  return file + ": line " + std::to_string(line) + ": " + problem;
}
/// "<file>: byte N: <problem>" (N counts decompressed bytes for .zst inputs)
inline std::string error_at_byte(const std::string& file, uint64_t offset, const std::string& problem) {
  return file + ": byte " + std::to_string(offset) + ": " + problem;
}

}  // namespace streamcvd
