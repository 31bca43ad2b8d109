// Buffered byte source over a file or standard input, decompressing zstd transparently
// (detected by the frame magic, whatever the extension). Readers pull bytes or lines from it;
// it never holds the whole file, only a buffer of a few MiB.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace streamcvd {

class InputStream {
 public:
  /// Opens `path` (a regular file or a pipe; "-" reads standard input, named "stdin" in
  /// messages). Throws InputError naming the file when it is missing, unreadable, a directory,
  /// a device (a terminal on stdin included) or socket, or empty (a FIFO without a writer
  /// reads as empty: opening never blocks).
  explicit InputStream(std::string path);
  ~InputStream();
  InputStream(const InputStream&) = delete;
  InputStream& operator=(const InputStream&) = delete;

  /// The name used in error messages: the path, or "stdin" for "-".
  const std::string& path() const { return path_; }
  bool compressed() const { return zstd_ != nullptr; }
  /// Size of the file on disk in bytes; 0 for a pipe (size unknown: empty files are rejected).
  uint64_t file_size() const { return file_size_; }
  /// Bytes of (decompressed) data consumed so far: the offset used in error messages.
  uint64_t offset() const { return consumed_before_buffer_ + pos_; }
  /// Bytes of the file itself behind offset(), for progress against file_size(): offset() for
  /// plain data, the compressed bytes read so far for zstd.
  uint64_t raw_offset() const { return zstd_ ? file_read_ : offset(); }
  /// 1-based number of the line last returned by next_line().
  uint64_t line_number() const { return line_; }

  /// Next line without its terminator (\n, \r\n or a lone \r). Returns false at end of data.
  /// The view stays valid until the next call on this stream. Lines over 256 MiB are an error.
  bool next_line(std::string_view& line);

  /// Copies up to n bytes; returns how many (fewer only at end of data).
  size_t read(void* dst, size_t n);
  /// Copies exactly n bytes or throws InputError "unexpected end of file while reading <what>".
  void read_exact(void* dst, size_t n, const char* what);

  /// Makes at least min(want, bytes left) bytes available and returns all buffered bytes;
  /// empty only at end of data. Pair with consume() for zero-copy parsing of binary blocks.
  std::span<const char> fill(size_t want);
  /// Marks n buffered bytes as used (n ≤ the size fill() returned).
  void consume(size_t n) { pos_ += n; }

  /// Upper bound on how many more elements of `min_bytes_each` bytes the data can hold, so that
  /// readers never size an allocation from an unchecked header count. For zstd input the bound
  /// assumes a compression ratio of at most 64:1 (vectors still grow past it if needed).
  uint64_t max_elements(uint64_t min_bytes_each) const;

  /// Throws InputError "<file>: byte N: <problem>" (or "line N" when lines are being read).
  [[noreturn]] void fail(const std::string& problem) const;

 private:
  size_t refill(size_t want);     // ensure `want` bytes after pos_ if available; returns count
  size_t read_source(char* dst, size_t n);  // raw or decompressed bytes from the file

  std::string path_;
  int fd_ = -1;
  bool owns_fd_ = true;           // false for standard input (never closed here)
  uint64_t file_size_ = 0;
  uint64_t file_read_ = 0;        // raw bytes read from the file
  struct Zstd;
  std::unique_ptr<Zstd> zstd_;
  std::vector<char> buffer_;
  size_t pos_ = 0, end_ = 0;      // unread bytes are buffer_[pos_, end_)
  uint64_t consumed_before_buffer_ = 0;
  uint64_t line_ = 0;
  bool line_mode_ = false;
  bool eof_ = false;
};

}  // namespace streamcvd
