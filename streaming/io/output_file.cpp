#include "streamcvd/streaming/io/output_file.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/types.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <stdexcept>

#include "streamcvd/core/mesh/anonymous_pages.h"
#include "streamcvd/core/mesh/errors.h"

namespace streamcvd {

namespace {

constexpr size_t kBufferSize = size_t(4) << 20;
constexpr size_t kZstdOutSize = size_t(1) << 20;
constexpr size_t kDirectAlign = 4096;               // O_DIRECT alignment of memory, offsets and sizes
constexpr size_t kDirectBlock = size_t(2) << 20;    // bounce buffer: requests large enough for full speed
constexpr size_t kDirectMin = size_t(1) << 20;      // smaller writes are not worth the bypass
constexpr size_t kMaxNameInTemp = 200;  // keeps ".<name>.tmp.<pid>.<16 hex>" under NAME_MAX

// ---- Registry of live temporary files ------------------------------------------------------
// A signal handler may run at any instruction of any thread, so it can neither lock nor
// allocate. Each slot is guarded by a seqlock-like word (generation << 2 | state): the handler
// copies a live slot and unlinks only if the word did not change meanwhile, so a slot being
// freed or reused concurrently is never half-read. All fields are atomics, hence no data race.
// The file is registered before it is created and unregistered after it is removed or
// renamed, so every temporary file that exists on disk is in the registry (unless all slots
// are taken, when the file merely loses signal cleanup).
constexpr int kSlots = 256;
constexpr size_t kSlotName = 256;
enum SlotState : uint64_t { kFree = 0, kBusy = 1, kLive = 2 };

struct Slot {
  std::atomic<uint64_t> word{0};
  std::atomic<int> dir_fd{-1};
  std::atomic<pid_t> pid{0};
  std::atomic<bool> directory{false};  // an empty folder this process made (CreatedDirectory)
  std::atomic<char> name[kSlotName];
};
Slot g_slots[kSlots];
std::atomic<bool> g_anonymous{true};

uint64_t next_word(uint64_t word, SlotState state) { return (((word >> 2) + 1) << 2) | state; }

int register_temp(int dir_fd, const std::string& name, bool directory = false) {
  if (name.size() >= kSlotName) return -1;
  for (int i = 0; i < kSlots; ++i) {
    Slot& s = g_slots[i];
    uint64_t w = s.word.load(std::memory_order_acquire);
    if ((w & 3) != kFree) continue;
    uint64_t busy = next_word(w, kBusy);
    if (!s.word.compare_exchange_strong(w, busy, std::memory_order_acq_rel)) continue;
    s.dir_fd.store(dir_fd, std::memory_order_relaxed);
    s.pid.store(::getpid(), std::memory_order_relaxed);
    s.directory.store(directory, std::memory_order_relaxed);
    for (size_t k = 0; k <= name.size(); ++k) s.name[k].store(name.c_str()[k], std::memory_order_relaxed);
    s.word.store(next_word(busy, kLive), std::memory_order_release);
    return i;
  }
  return -1;
}

void unregister_temp(int slot) {
  if (slot < 0) return;
  Slot& s = g_slots[slot];
  s.word.store(next_word(s.word.load(std::memory_order_relaxed), kFree), std::memory_order_release);
}

void cleanup_handler(int sig) {
  remove_temp_files_now();
  // SA_RESETHAND restored the default action; the signal is blocked while we run, so it is
  // delivered (and kills the process with the right status) as soon as the handler returns.
  ::raise(sig);
}

uint64_t random_suffix() {
  // Uniqueness, not secrecy: O_EXCL catches collisions and we retry.
  static std::atomic<uint64_t> counter{0};
  uint64_t x = uint64_t(std::chrono::steady_clock::now().time_since_epoch().count()) ^
               (uint64_t(::getpid()) << 32) ^ (counter.fetch_add(1) * 0x9E3779B97F4A7C15ull);
  x ^= x >> 30;  // splitmix64 finaliser
  x *= 0xBF58476D1CE4E5B9ull;
  x ^= x >> 27;
  x *= 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

std::string hex64(uint64_t v) {
  static const char digits[] = "0123456789abcdef";
  std::string s(16, '0');
  for (int i = 15; i >= 0; --i, v >>= 4) s[size_t(i)] = digits[v & 15];
  return s;
}

}  // namespace

void remove_temp_files_now() noexcept {
  const pid_t self = ::getpid();  // a forked child must not delete its parent's files
  // Files first, then the folders made for them: a folder goes only once empty (rmdir fails
  // otherwise), and a nested one before its parent, hence one pass per level (a few at most).
  for (int pass = 0; pass < 4; ++pass) {
    for (Slot& s : g_slots) {
      uint64_t w1 = s.word.load(std::memory_order_acquire);
      if ((w1 & 3) != kLive) continue;
      int dir_fd = s.dir_fd.load(std::memory_order_relaxed);
      pid_t pid = s.pid.load(std::memory_order_relaxed);
      const bool directory = s.directory.load(std::memory_order_relaxed);
      if (directory != (pass > 0)) continue;
      char name[kSlotName];
      for (size_t k = 0; k < kSlotName; ++k) {
        name[k] = s.name[k].load(std::memory_order_relaxed);
        if (name[k] == '\0') break;
      }
      name[kSlotName - 1] = '\0';
      std::atomic_thread_fence(std::memory_order_acquire);
      if (s.word.load(std::memory_order_relaxed) != w1 || pid != self) continue;
      ::unlinkat(dir_fd, name, directory ? AT_REMOVEDIR : 0);
    }
  }
}

CreatedDirectory::CreatedDirectory(const std::string& path) {
  namespace fs = std::filesystem;
  // The missing levels, outermost first: each is made, then registered for removal.
  std::vector<fs::path> missing;
  std::error_code ec;
  for (fs::path p = fs::path(path).lexically_normal(); !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
    if (p.has_filename()) missing.push_back(p);
    if (p == p.parent_path()) break;
  }
  try {
    for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
      const std::string parent = it->has_parent_path() ? it->parent_path().string() : ".";
      const std::string name = it->filename().string();
      const int parent_fd = ::open(parent.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
      if (parent_fd < 0) throw OutputError(error_at(path, "cannot open folder '" + parent + "': " + std::strerror(errno)));
      const int slot = register_temp(parent_fd, name, /*directory=*/true);  // before: see the registry
      if (::mkdirat(parent_fd, name.c_str(), 0777) != 0) {
        const int e = errno;
        unregister_temp(slot);
        ::close(parent_fd);
        if (e == EEXIST) continue;  // made meanwhile by someone else: theirs, not ours to remove
        throw OutputError(error_at(path, "cannot create folder: " + std::string(std::strerror(e))));
      }
      made_.push_back({parent_fd, name, slot});
    }
  } catch (...) {
    remove_made();
    throw;
  }
  std::error_code is_dir_error;
  if (!fs::is_directory(path, is_dir_error)) {
    remove_made();
    throw OutputError(error_at(path, "is not a folder"));
  }
}

CreatedDirectory::~CreatedDirectory() { remove_made(); }

void CreatedDirectory::keep() noexcept {
  for (Level& level : made_) {
    unregister_temp(level.slot);
    ::close(level.parent_fd);
  }
  made_.clear();
}

void CreatedDirectory::remove_made() noexcept {
  for (auto it = made_.rbegin(); it != made_.rend(); ++it) {  // innermost first; only if empty
    ::unlinkat(it->parent_fd, it->name.c_str(), AT_REMOVEDIR);
    unregister_temp(it->slot);
    ::close(it->parent_fd);
  }
  made_.clear();
}

void ignore_file_size_signal() {
  static std::once_flag once;
  std::call_once(once, [] {
    struct sigaction old {};
    if (::sigaction(SIGXFSZ, nullptr, &old) == 0 && !(old.sa_flags & SA_SIGINFO) && old.sa_handler == SIG_DFL) {
      struct sigaction ign {};
      ign.sa_handler = SIG_IGN;
      sigemptyset(&ign.sa_mask);
      ::sigaction(SIGXFSZ, &ign, nullptr);
    }
  });
}

std::string work_file_problem(int err) {
  std::string problem = std::strerror(err);
  if (err == ENOSPC || err == EDQUOT || err == EFBIG)
    problem += " (work folder full or at a file size limit: free space, or choose another with --work-dir)";
  return problem;
}

void set_anonymous_temp_files(bool enabled) { g_anonymous.store(enabled); }

void install_signal_cleanup() {
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
    struct sigaction old {};
    if (::sigaction(sig, nullptr, &old) != 0) continue;
    if ((old.sa_flags & SA_SIGINFO) || old.sa_handler != SIG_DFL) continue;  // not ours to replace
    struct sigaction sa {};
    sa.sa_handler = cleanup_handler;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESETHAND;
    ::sigaction(sig, &sa, nullptr);
  }
}

// ---- AtomicOutputFile ----------------------------------------------------------------------

struct AtomicOutputFile::Zstd {
  ZSTD_CCtx* ctx = nullptr;
  std::unique_ptr<char[]> out;
  ~Zstd() { ZSTD_freeCCtx(ctx); }
};

AtomicOutputFile::AtomicOutputFile(std::string path, bool compress, int zstd_level) : path_(std::move(path)) {
  ignore_file_size_signal();
  size_t slash = path_.find_last_of('/');
  folder_ = slash == std::string::npos ? "." : slash == 0 ? "/" : path_.substr(0, slash);
  name_ = slash == std::string::npos ? path_ : path_.substr(slash + 1);
  if (name_.empty() || name_ == "." || name_ == "..")
    throw OutputError(error_at(path_, "not a file name"));

  dir_fd_ = ::open(folder_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir_fd_ < 0) {
    int e = errno;
    throw OutputError(error_at(path_, e == ENOTDIR ? "'" + folder_ + "' is not a folder"
                                                   : "cannot open output folder '" + folder_ + "': " + std::strerror(e)));
  }
  struct stat st {};
  if (::fstatat(dir_fd_, name_.c_str(), &st, 0) == 0 && S_ISDIR(st.st_mode)) {
    ::close(dir_fd_);
    dir_fd_ = -1;
    throw OutputError(error_at(path_, "is a directory"));
  }

  std::string stem(1, '.');
  stem.append(name_, 0, kMaxNameInTemp).append(".tmp.").append(std::to_string(::getpid())).append(".");
  // An anonymous file (O_TMPFILE) has no name until commit() links it in: even SIGKILL or a
  // crash leaves nothing behind. File systems without it get a named temporary file instead,
  // which the signal registry removes on SIGINT/SIGTERM/SIGHUP.
  if (g_anonymous.load(std::memory_order_relaxed)) fd_ = ::openat(dir_fd_, ".", O_TMPFILE | O_RDWR | O_CLOEXEC, 0666);
  anonymous_ = fd_ >= 0;
  for (int attempt = 0; fd_ < 0; ++attempt) {
    temp_name_ = stem + hex64(random_suffix());
    slot_ = register_temp(dir_fd_, temp_name_);  // before creating: see the registry comment
    fd_ = ::openat(dir_fd_, temp_name_.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd_ >= 0) break;
    int e = errno;
    unregister_temp(slot_);
    slot_ = -1;
    if (e == EEXIST && attempt < 16) continue;
    ::close(dir_fd_);
    dir_fd_ = -1;
    throw OutputError(error_at(path_, "cannot create a file in '" + folder_ + "': " + std::strerror(e)));
  }

  buffer_ = std::make_unique_for_overwrite<char[]>(kBufferSize);
  capacity_ = kBufferSize;
  if (compress) {
    zstd_ = std::make_unique<Zstd>();
    zstd_->ctx = ZSTD_createCCtx();
    zstd_->out = std::make_unique_for_overwrite<char[]>(kZstdOutSize);
    if (!zstd_->ctx) fail("cannot create a zstd compression context");
    size_t r = ZSTD_CCtx_setParameter(zstd_->ctx, ZSTD_c_compressionLevel, zstd_level);
    if (!ZSTD_isError(r)) r = ZSTD_CCtx_setParameter(zstd_->ctx, ZSTD_c_checksumFlag, 1);
    if (ZSTD_isError(r)) fail(std::string("zstd: ") + ZSTD_getErrorName(r));
  }
}

AtomicOutputFile::~AtomicOutputFile() { abandon(); }

std::string AtomicOutputFile::temp_path() const {
  if (done_ || anonymous_) return {};
  return folder_ == "/" ? "/" + temp_name_ : folder_ + "/" + temp_name_;
}

void AtomicOutputFile::abandon() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  if (!done_ && dir_fd_ >= 0 && !temp_name_.empty() && !anonymous_) ::unlinkat(dir_fd_, temp_name_.c_str(), 0);
  unregister_temp(slot_);  // only after the file is gone, and before dir_fd_ can be reused
  slot_ = -1;
  if (dir_fd_ >= 0) ::close(dir_fd_);
  dir_fd_ = -1;
  done_ = true;
  buffer_.reset();
  capacity_ = used_ = 0;  // so prepare() on a dead object reaches make_room() and throws
  zstd_.reset();
}

void AtomicOutputFile::fail(const std::string& problem) {
  abandon();
  throw OutputError(error_at(path_, problem));
}

void AtomicOutputFile::write_raw(const char* data, size_t n) {
  while (n > 0) {
    ssize_t w = ::write(fd_, data, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      fail(std::string("write failed: ") + std::strerror(errno));
    }
    if (w == 0) fail("write failed: no progress");
    data += w;
    n -= size_t(w);
  }
}

// Hands the buffered bytes to the file, through the compressor if any.
void AtomicOutputFile::flush_buffer() {
  if (used_ == 0) return;
  if (!zstd_) {
    write_raw(buffer_.get(), used_);
  } else {
    ZSTD_inBuffer in{buffer_.get(), used_, 0};
    while (in.pos < in.size) {
      ZSTD_outBuffer out{zstd_->out.get(), kZstdOutSize, 0};
      size_t r = ZSTD_compressStream2(zstd_->ctx, &out, &in, ZSTD_e_continue);
      if (ZSTD_isError(r)) fail(std::string("zstd: ") + ZSTD_getErrorName(r));
      write_raw(zstd_->out.get(), out.pos);
    }
  }
  flushed_ += used_;
  used_ = 0;
}

void AtomicOutputFile::make_room(size_t n) {
  if (done_) throw std::logic_error(path_ + ": write after commit or failure");
  if (n > kMaxPrepare) throw std::logic_error(path_ + ": prepare() larger than kMaxPrepare");
  flush_buffer();
}

void AtomicOutputFile::write(const void* data, size_t n) {
  if (done_) throw std::logic_error(path_ + ": write after commit or failure");
  const char* p = static_cast<const char*>(data);
  while (n > 0) {
    if (used_ == capacity_) flush_buffer();
    size_t take = std::min(n, capacity_ - used_);
    if (used_ == 0 && !zstd_ && n >= capacity_) {
      // Large uncompressed block: skip the copy, go straight to the file.
      write_raw(p, n);
      flushed_ += n;
      written_ += n;
      return;
    }
    std::memcpy(buffer_.get() + used_, p, take);
    used_ += take;
    written_ += take;
    p += take;
    n -= take;
  }
}

void AtomicOutputFile::write_direct(const void* data, size_t n) {
  if (done_) throw std::logic_error(path_ + ": write after commit or failure");
  if (zstd_ || n < kDirectMin) return write(data, n);
  flush_buffer();
  const int plain = ::fcntl(fd_, F_GETFL);
  if (flushed_ % kDirectAlign != 0 || plain < 0 || ::fcntl(fd_, F_SETFL, plain | O_DIRECT) != 0)
    return write(data, n);
  // Mapped, not malloc'ed: page-aligned, and returned to the system at once (a freed malloc
  // block of this size may stay resident in a thread's arena and add to the peak RSS).
  struct Unmap {
    void operator()(char* p) const { unmap_anonymous_pages(p, kDirectBlock); }
  };
  std::unique_ptr<char, Unmap> bounce(static_cast<char*>(map_anonymous_pages(kDirectBlock)));
  const char* p = static_cast<const char*>(data);
  size_t left = n;
  bool padded = false;
  while (bounce && left > 0) {
    const size_t take = std::min(left, kDirectBlock);
    const size_t whole = (take + kDirectAlign - 1) / kDirectAlign * kDirectAlign;
    // Aligned source blocks (e.g. the store's page-aligned arrays) are written as they are; the
    // rest and the padded tail go through the bounce buffer.
    const bool in_place = reinterpret_cast<uintptr_t>(p) % kDirectAlign == 0 && take == whole;
    if (!in_place) {
      std::memcpy(bounce.get(), p, take);
      std::memset(bounce.get() + take, 0, whole - take);  // the tail block is padded, truncated below
    }
    const char* from = in_place ? p : bounce.get();
    size_t done = 0;
    while (done < whole) {
      ssize_t w = ::write(fd_, from + done, whole - done);
      if (w < 0 && errno == EINTR) continue;
      if (w < 0 && errno == EINVAL && done == 0) break;  // O_DIRECT refused (file system): fall back
      if (w < 0) fail(std::string("write failed: ") + std::strerror(errno));
      if (w == 0) fail("write failed: no progress");
      done += size_t(w);
    }
    if (done < whole) break;
    padded = whole != take;
    p += take;
    left -= take;
    flushed_ += take;
    written_ += take;
  }
  if (::fcntl(fd_, F_SETFL, plain) != 0) fail(std::string("fcntl failed: ") + std::strerror(errno));
  if (padded && (::ftruncate(fd_, off_t(flushed_)) != 0 || ::lseek(fd_, off_t(flushed_), SEEK_SET) < 0))
    fail(std::string("truncate failed: ") + std::strerror(errno));
  if (left > 0) write(p, left);  // no bounce buffer, or O_DIRECT unsupported here
}

void AtomicOutputFile::sync() {
  if (done_) throw std::logic_error(path_ + ": sync after commit or failure");
  flush_buffer();
  if (::fdatasync(fd_) != 0) fail(std::string("fsync failed: ") + std::strerror(errno));
  synced_ = flushed_;
}

void AtomicOutputFile::patch(uint64_t offset, const void* data, size_t n) {
  if (done_) throw std::logic_error(path_ + ": patch after commit or failure");
  if (zstd_) throw std::logic_error(path_ + ": patch() on a compressed file");
  if (offset > written_ || n > written_ - offset) throw std::logic_error(path_ + ": patch() past the written bytes");
  const char* p = static_cast<const char*>(data);
  synced_ = ~uint64_t(0);  // the patched bytes are not durable yet
  // Part already in the file: pwrite. Part still in the buffer: overwrite it there.
  while (n > 0 && offset < flushed_) {
    size_t take = size_t(std::min<uint64_t>(n, flushed_ - offset));
    ssize_t w = ::pwrite(fd_, p, take, off_t(offset));
    if (w < 0) {
      if (errno == EINTR) continue;
      fail(std::string("write failed: ") + std::strerror(errno));
    }
    if (w == 0) fail("write failed: no progress");
    p += w;
    offset += uint64_t(w);
    n -= size_t(w);
  }
  if (n > 0) std::memcpy(buffer_.get() + (offset - flushed_), p, n);
}

void AtomicOutputFile::read_back(uint64_t offset, void* dst, size_t n) {
  if (done_) throw std::logic_error(path_ + ": read_back after commit or failure");
  if (zstd_) throw std::logic_error(path_ + ": read_back() on a compressed file");
  if (offset > written_ || n > written_ - offset) throw std::logic_error(path_ + ": read_back() past the written bytes");
  flush_buffer();
  char* p = static_cast<char*>(dst);
  for (size_t done = 0; done < n;) {
    const ssize_t r = ::pread(fd_, p + done, n - done, off_t(offset + done));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) fail(std::string("cannot read back: ") + (r < 0 ? std::strerror(errno) : "short read"));
    done += size_t(r);
  }
  ::posix_fadvise(fd_, off_t(offset), off_t(n), POSIX_FADV_DONTNEED);
}

void AtomicOutputFile::commit(bool sync_folder) {
  if (done_) throw std::logic_error(path_ + ": commit after commit or failure");
  flush_buffer();
  if (zstd_) {
    ZSTD_inBuffer in{nullptr, 0, 0};
    size_t remaining;
    do {
      ZSTD_outBuffer out{zstd_->out.get(), kZstdOutSize, 0};
      remaining = ZSTD_compressStream2(zstd_->ctx, &out, &in, ZSTD_e_end);
      if (ZSTD_isError(remaining)) fail(std::string("zstd: ") + ZSTD_getErrorName(remaining));
      write_raw(zstd_->out.get(), out.pos);
    } while (remaining != 0);
    synced_ = ~uint64_t(0);  // the frame's epilogue went out after any sync()
  }
  if (synced_ != flushed_ && ::fsync(fd_) != 0) fail(std::string("fsync failed: ") + std::strerror(errno));
  if (anonymous_) link_anonymous();
  int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) fail(std::string("close failed: ") + std::strerror(errno));
  if (::renameat(dir_fd_, temp_name_.c_str(), dir_fd_, name_.c_str()) != 0)
    fail(std::string("cannot rename the temporary file into place: ") + std::strerror(errno));
  done_ = true;  // the temporary name is gone: abandon() must not unlink it any more
  // Make the rename itself durable. Some file systems cannot fsync a directory (EINVAL).
  if (sync_folder && ::fsync(dir_fd_) != 0 && errno != EINVAL && errno != EROFS) {
    int e = errno;
    ::unlinkat(dir_fd_, name_.c_str(), 0);
    abandon();
    throw OutputError(error_at(path_, std::string("fsync of the folder failed: ") + std::strerror(e)));
  }
  abandon();
}

// Gives the anonymous file a temporary name, so that the rename below replaces the final path
// atomically (linkat cannot overwrite). The name is registered for signal cleanup first, and the
// file is named only once fully written and synced: the window is a rename long.
void AtomicOutputFile::link_anonymous() {
  const std::string proc = "/proc/self/fd/" + std::to_string(fd_);
  for (int attempt = 0;; ++attempt) {
    temp_name_ = "." + name_.substr(0, kMaxNameInTemp) + ".tmp." + std::to_string(::getpid()) + "." +
                 hex64(random_suffix());
    slot_ = register_temp(dir_fd_, temp_name_);
    int r = ::linkat(AT_FDCWD, proc.c_str(), dir_fd_, temp_name_.c_str(), AT_SYMLINK_FOLLOW);
    if (r != 0 && errno == ENOENT) r = ::linkat(fd_, "", dir_fd_, temp_name_.c_str(), AT_EMPTY_PATH);  // no /proc
    if (r == 0) break;
    const int e = errno;
    unregister_temp(slot_);
    slot_ = -1;
    if (e == EEXIST && attempt < 16) continue;
    fail(std::string("cannot link the written file into '") + folder_ + "': " + std::strerror(e));
  }
  anonymous_ = false;  // named now: abandon() removes it if the rename fails
}

void sync_directory(const std::string& folder) {
  int fd = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) throw OutputError(error_at(folder, std::string("cannot open folder: ") + std::strerror(errno)));
  const int e = ::fsync(fd) != 0 ? errno : 0;
  ::close(fd);
  if (e != 0 && e != EINVAL && e != EROFS)
    throw OutputError(error_at(folder, std::string("fsync of the folder failed: ") + std::strerror(e)));
}

void write_file_atomic(const std::string& path, std::string_view contents) {
  AtomicOutputFile out(path);
  out.write(contents);
  out.commit();
}

}  // namespace streamcvd
