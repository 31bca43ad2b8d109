#include "streamcvd/streaming/io/input_stream.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <new>

#include "streamcvd/core/mesh/errors.h"

namespace streamcvd {

namespace {
constexpr size_t kBufferSize = size_t(4) << 20;
constexpr size_t kMaxLine = size_t(256) << 20;
constexpr unsigned char kZstdMagic[4] = {0x28, 0xB5, 0x2F, 0xFD};
}  // namespace

struct InputStream::Zstd {
  ZSTD_DCtx* ctx = nullptr;
  std::vector<char> in;
  ZSTD_inBuffer input{nullptr, 0, 0};
  bool frame_open = false;  // last ZSTD_decompressStream returned non-zero (frame incomplete)
  ~Zstd() { ZSTD_freeDCtx(ctx); }
};

InputStream::InputStream(std::string path) : path_(std::move(path)) {
  if (path_ == "-") {
    // Standard input: already open, and left open (and blocking as it is) for the caller.
    path_ = "stdin";
    fd_ = STDIN_FILENO;
    owns_fd_ = false;
  } else {
    // O_NONBLOCK: opening a FIFO that has no writer would otherwise block forever. The type is
    // then checked on the open descriptor (no window for the path to change in between).
    fd_ = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (fd_ < 0) throw InputError(error_at(path_, std::strerror(errno)));
  }
  auto close_fd = [this] {
    if (owns_fd_ && fd_ >= 0) ::close(fd_);
    fd_ = -1;
  };
  struct stat st {};
  const char* problem = nullptr;
  if (::fstat(fd_, &st) != 0) problem = std::strerror(errno);
  else if (S_ISDIR(st.st_mode)) problem = "is a directory, not a mesh file";
  else if (!S_ISREG(st.st_mode) && !S_ISFIFO(st.st_mode)) problem = "not a regular file or pipe";
  // Blocking reads from here on (a pipe's writer may be slower than us). A FIFO without a
  // writer then reads as end of file at once, hence "file is empty" below.
  else if (owns_fd_ && ::fcntl(fd_, F_SETFL, ::fcntl(fd_, F_GETFL) & ~O_NONBLOCK) != 0) problem = std::strerror(errno);
  if (problem) {
    close_fd();
    throw InputError(error_at(path_, problem));
  }
  file_size_ = S_ISREG(st.st_mode) ? uint64_t(st.st_size) : 0;
  if (!owns_fd_ && file_size_ > 0) {  // "< file" on stdin: what is left after the current offset
    const off_t at = ::lseek(fd_, 0, SEEK_CUR);
    if (at > 0) file_size_ = at < off_t(file_size_) ? file_size_ - uint64_t(at) : 0;
  }
#ifdef POSIX_FADV_SEQUENTIAL
  ::posix_fadvise(fd_, 0, 0, POSIX_FADV_SEQUENTIAL);
#endif
  try {  // the destructor does not run when the constructor throws: close the file here
    // A small file gets a small buffer (a mesh reader opens many of them in tests and fuzzing);
    // refill() grows it when a zstd frame inflates or a request needs more.
    buffer_.resize(file_size_ > 0 ? size_t(std::clamp<uint64_t>(file_size_ + 1, 4096, kBufferSize)) : kBufferSize);
    // Sniff the zstd magic from the first raw bytes, then keep them as input of the chosen path.
    size_t got = read_source(buffer_.data(), 4);
    if (got == 0)
      throw InputError(error_at(path_, S_ISFIFO(st.st_mode) ? "pipe is empty (no writer)" : "file is empty"));
    if (got == 4 && std::memcmp(buffer_.data(), kZstdMagic, 4) == 0) {
      buffer_.resize(size_t(std::clamp<uint64_t>(16 * file_size_, 1 << 16, kBufferSize)));
      zstd_ = std::make_unique<Zstd>();
      zstd_->ctx = ZSTD_createDCtx();
      if (!zstd_->ctx) throw std::bad_alloc();
      zstd_->in.resize(ZSTD_DStreamInSize());
      std::memcpy(zstd_->in.data(), kZstdMagic, 4);
      zstd_->input = {zstd_->in.data(), 4, 0};
      end_ = 0;
    } else {
      end_ = got;
    }
  } catch (...) {
    close_fd();
    throw;
  }
}

InputStream::~InputStream() {
  if (owns_fd_ && fd_ >= 0) ::close(fd_);
}

size_t InputStream::read_source(char* dst, size_t n) {
  if (!zstd_) {
    size_t total = 0;
    while (total < n) {
      ssize_t r = ::read(fd_, dst + total, n - total);
      if (r < 0) {
        if (errno == EINTR) continue;
        throw InputError(error_at(path_, std::string("read error: ") + std::strerror(errno)));
      }
      if (r == 0) break;
      total += size_t(r);
      file_read_ += uint64_t(r);
    }
    return total;
  }
  // Streaming decompression (zstd examples/streaming_decompression.c): refill the input buffer
  // from the file, decompress into dst; end of file inside a frame is an error.
  ZSTD_outBuffer out{dst, n, 0};
  while (out.pos < out.size) {
    if (zstd_->input.pos == zstd_->input.size) {
      ssize_t r;
      do r = ::read(fd_, zstd_->in.data(), zstd_->in.size());
      while (r < 0 && errno == EINTR);
      if (r < 0) throw InputError(error_at(path_, std::string("read error: ") + std::strerror(errno)));
      if (r == 0) {
        if (zstd_->frame_open)
          throw InputError(error_at_byte(path_, file_read_, "truncated zstd frame (compressed data ends early)"));
        break;
      }
      file_read_ += uint64_t(r);
      zstd_->input = {zstd_->in.data(), size_t(r), 0};
    }
    size_t ret = ZSTD_decompressStream(zstd_->ctx, &out, &zstd_->input);
    if (ZSTD_isError(ret))
      throw InputError(error_at_byte(path_, file_read_, std::string("corrupt zstd data: ") + ZSTD_getErrorName(ret)));
    zstd_->frame_open = ret != 0;
  }
  return out.pos;
}

size_t InputStream::refill(size_t want) {
  size_t have = end_ - pos_;
  if (have >= want || eof_) return have;
  if (want > buffer_.size() - pos_) {
    // Slide unread bytes to the front, growing the buffer if one request exceeds it.
    consumed_before_buffer_ += pos_;
    std::memmove(buffer_.data(), buffer_.data() + pos_, have);
    pos_ = 0;
    end_ = have;
    // Grow for a request larger than the buffer, but no further than the data can go: a 1 MiB
    // request near the end of a small file needs only what is left (+1 to see the end).
    size_t need = want;
    if (!zstd_ && file_size_ > 0)
      need = size_t(std::min<uint64_t>(want, have + (file_size_ > file_read_ ? file_size_ - file_read_ : 0) + 1));
    if (need > buffer_.size()) buffer_.resize(std::max(need, std::min(buffer_.size() * 2, kBufferSize)));
  }
  while (end_ - pos_ < want && !eof_) {
    // Full but more wanted: a zstd frame inflating, or a file that grew since it was opened.
    if (end_ == buffer_.size()) buffer_.resize(buffer_.size() * 2);
    size_t got = read_source(buffer_.data() + end_, buffer_.size() - end_);
    if (got == 0) eof_ = true;
    end_ += got;
  }
  return end_ - pos_;
}

std::span<const char> InputStream::fill(size_t want) {
  size_t have = refill(std::max(want, size_t(1)));
  return {buffer_.data() + pos_, have};
}

size_t InputStream::read(void* dst, size_t n) {
  char* out = static_cast<char*>(dst);
  size_t done = 0;
  while (done < n) {
    size_t have = refill(std::min(n - done, kBufferSize));
    if (have == 0) break;
    size_t take = std::min(have, n - done);
    std::memcpy(out + done, buffer_.data() + pos_, take);
    pos_ += take;
    done += take;
  }
  return done;
}

void InputStream::read_exact(void* dst, size_t n, const char* what) {
  if (read(dst, n) != n) fail(std::string("unexpected end of file while reading ") + what);
}

bool InputStream::next_line(std::string_view& line) {
  line_mode_ = true;
  size_t scan_from = pos_;
  for (;;) {
    const char* base = buffer_.data();
    for (size_t i = scan_from; i < end_; ++i) {
      char c = base[i];
      if (c != '\n' && c != '\r') continue;
      if (c == '\r' && i + 1 == end_ && !eof_) {
        // Need one more byte to tell "\r\n" from a lone "\r".
        size_t rel = i - pos_;
        refill(rel + 2);
        base = buffer_.data();
        i = pos_ + rel;
      }
      line = std::string_view(base + pos_, i - pos_);
      size_t next = i + 1;
      if (c == '\r' && next < end_ && base[next] == '\n') ++next;
      pos_ = next;
      ++line_;
      return true;
    }
    size_t have = end_ - pos_;
    if (have > kMaxLine) {  // also for a last line without terminator
      ++line_;
      fail("line longer than 256 MiB");
    }
    if (eof_) {
      if (have == 0) return false;
      line = std::string_view(buffer_.data() + pos_, have);
      pos_ = end_;
      ++line_;
      return true;
    }
    size_t scanned = have;
    // Never ask for more than one byte past the limit: the buffer stays under ~256 MiB.
    refill(std::min(std::max(have * 2, have + (size_t(1) << 16)), kMaxLine + 1));
    scan_from = pos_ + scanned;
  }
}

uint64_t InputStream::max_elements(uint64_t min_bytes_each) const {
  if (min_bytes_each == 0) min_bytes_each = 1;
  uint64_t remaining_raw = file_size_ > file_read_ ? file_size_ - file_read_ : 0;
  uint64_t remaining = zstd_ ? (remaining_raw + zstd_->input.size - zstd_->input.pos) * 64 : remaining_raw;
  remaining += end_ - pos_;
  return remaining / min_bytes_each;
}

void InputStream::fail(const std::string& problem) const {
  if (line_mode_) throw InputError(error_at_line(path_, line_, problem));
  throw InputError(error_at_byte(path_, offset(), problem));
}

}  // namespace streamcvd
