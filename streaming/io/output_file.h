// Atomic output files: every byte streamcvd writes goes to an anonymous file (O_TMPFILE) in the
// destination folder that is fsynced, linked under a temporary name and renamed onto the final
// path only on commit(). A failure, an exception, a signal, even SIGKILL or a crash, never leaves
// a partial file behind. On file systems without O_TMPFILE the file is a named temporary
// (".<name>.tmp.<pid>.<random>") from the start, removed on failure and (after
// install_signal_cleanup()) on SIGINT/SIGTERM/SIGHUP.
//
// Seeking back: patch() rewrites already written bytes of an *uncompressed* file (a streamed
// writer that learns its face count at the end patches it into a fixed-width header field).
// Compressed output is a single forward-only zstd stream, so a writer that wants ".zst" must know
// its counts before it starts (write_mesh always does).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace streamcvd {

/// One output file being written. Not thread-safe: one thread writes a given file (any number
/// of files may be open at once, from any threads). Not movable: its registry slot names it.
class AtomicOutputFile {
 public:
  /// Opens a temporary file next to `path`. With `compress`, everything written goes through one
  /// streaming zstd frame (with checksum) at `zstd_level`. Throws OutputError "<path>: <problem>"
  /// when the folder is missing, not a folder, not writable, or `path` names a directory.
  /// Whether new AtomicOutputFiles start anonymous (O_TMPFILE, the default where the file system
/// supports it) or as named temporaries (the fallback path). For tests of the fallback.
void set_anonymous_temp_files(bool enabled);

/// Ignores SIGXFSZ process-wide (if it has its default action) so that a file-size limit
  /// (`ulimit -f`) surfaces as an EFBIG error instead of killing the process.
  explicit AtomicOutputFile(std::string path, bool compress = false, int zstd_level = 3);
  /// Without commit(): closes and removes the temporary file. Never throws.
  ~AtomicOutputFile();
  AtomicOutputFile(const AtomicOutputFile&) = delete;
  AtomicOutputFile& operator=(const AtomicOutputFile&) = delete;

  /// Appends n bytes (buffered, 4 MiB). Throws OutputError on a write error (disk full, EFBIG,
  /// I/O error); the temporary file is then already removed and the object is dead.
  void write(const void* data, size_t n);
  void write(std::string_view s) { write(s.data(), s.size()); }

  /// Zero-copy formatting: returns a pointer to at least n (≤ 1 MiB) writable bytes at the end
  /// of the buffer; advance(k) then appends the first k ≤ n of them.
  char* prepare(size_t n) {
    if (capacity_ - used_ < n) make_room(n);
    return buffer_.get() + used_;
  }
  void advance(size_t k) {
    used_ += k;
    written_ += k;
  }

  /// Appends n bytes like write(), but large uncompressed blocks bypass the page cache (O_DIRECT,
  /// straight from `data` where it is 4096-aligned, else through an aligned bounce buffer) when
  /// the file system allows it, else plain write(). For
  /// big arrays not read back soon: on this project's VM disks ~5x faster than buffered writes
  /// followed by fsync. Throws OutputError like write().
  void write_direct(const void* data, size_t n);

  /// Hands the buffered bytes to the file (not durable yet). Throws OutputError.
  void flush() { flush_buffer(); }

  /// Flushes and makes the temporary file's bytes durable (fdatasync) without renaming it, so a
  /// caller can sync many files (e.g. in parallel) before committing any; commit() then skips
  /// its own fsync unless more bytes were written. Throws OutputError (temp file removed).
  void sync();

  /// Overwrites bytes [offset, offset + n) that were already written (buffered or flushed).
  /// Uncompressed files only: throws std::logic_error for a compressed file or a range past
  /// bytes_written(); OutputError on an I/O error.
  void patch(uint64_t offset, const void* data, size_t n);

  /// Copies n bytes at `offset` of what was written (uncompressed files; flushes first), for a
  /// writer that reads its own output back. The bytes read are dropped from the page cache.
  /// Throws std::logic_error past bytes_written(), OutputError on an I/O error.
  void read_back(uint64_t offset, void* dst, size_t n);

  /// Flushes, fsyncs the file, renames it onto the final path and fsyncs the folder (with
  /// `sync_folder` false the caller does that once for many files, see sync_directory()).
  /// Throws OutputError (and removes the temporary file) on failure.
  void commit(bool sync_folder = true);

  /// The open descriptor (e.g. to map a finished scratch file that is never committed); −1 once
  /// committed or failed.
  int descriptor() const { return fd_; }
  /// Logical bytes written so far (before compression).
  uint64_t bytes_written() const { return written_; }
  const std::string& path() const { return path_; }
  /// Full path of the named temporary file (empty once committed or failed, and for an
  /// anonymous file, which has no name until commit()).
  std::string temp_path() const;
  bool compressed() const { return zstd_ != nullptr; }

  static constexpr size_t kMaxPrepare = size_t(1) << 20;

 private:
  void make_room(size_t n);
  void flush_buffer();                           // buffer_ → file (compressing if needed)
  void write_raw(const char* data, size_t n);    // → fd, no buffering
  [[noreturn]] void fail(const std::string& problem);
  void abandon() noexcept;                       // close + unlink temp + unregister
  void link_anonymous();                         // O_TMPFILE file → temporary name, before the rename

  std::string path_;
  std::string folder_;      // destination folder as given ("." when the path has none)
  std::string name_;        // final file name inside the folder
  std::string temp_name_;   // temporary file name inside the folder
  int dir_fd_ = -1;
  int fd_ = -1;
  int slot_ = -1;           // registry slot, -1 when not registered
  std::unique_ptr<char[]> buffer_;
  size_t capacity_ = 0, used_ = 0;
  uint64_t written_ = 0;    // logical bytes (buffered + flushed)
  uint64_t flushed_ = 0;    // logical bytes handed to the file or compressor
  uint64_t synced_ = ~uint64_t(0);  // flushed_ at the last sync(), if any
  struct Zstd;
  std::unique_ptr<Zstd> zstd_;
  bool done_ = false;       // committed or failed
  bool anonymous_ = false;  // O_TMPFILE: no name on disk until commit()
};

/// A folder a job makes for its output (with any missing parents), removed again, where still
/// empty, unless keep() is called: an error, an exception or SIGINT/SIGTERM/SIGHUP (the signal
/// cleanup of install_signal_cleanup) leaves no empty store folder behind. A folder that
/// existed is left alone. Throws OutputError naming the folder. Not thread-safe.
class CreatedDirectory {
 public:
  explicit CreatedDirectory(const std::string& path);
  ~CreatedDirectory();
  CreatedDirectory(const CreatedDirectory&) = delete;
  CreatedDirectory& operator=(const CreatedDirectory&) = delete;

  /// The job succeeded: the folder stays.
  void keep() noexcept;

 private:
  struct Level {
    int parent_fd;  // open for the lifetime, so that a rename of the parent cannot misdirect rmdir
    std::string name;
    int slot;  // signal registry slot (-1: none free)
  };
  void remove_made() noexcept;
  std::vector<Level> made_;  // outermost first
};

/// fsyncs a folder, making renames and removals inside it durable. File systems that cannot
/// fsync a folder (EINVAL, EROFS) are accepted. Throws OutputError "<folder>: <problem>".
void sync_directory(const std::string& folder);

/// Writes `contents` to `path` atomically (same guarantees as AtomicOutputFile). For small
/// outputs such as JSON reports. Throws OutputError.
void write_file_atomic(const std::string& path, std::string_view contents);

/// Installs SIGINT, SIGTERM and SIGHUP handlers that remove every live temporary file of this
/// process and then re-raise the signal with its default action. Signals whose disposition is
/// not the default (e.g. ignored under nohup, or a handler of the application) are left alone.
/// Idempotent; call once early in main().
void install_signal_cleanup();

/// Whether new AtomicOutputFiles start anonymous (O_TMPFILE, the default where the file system
/// supports it) or as named temporaries (the fallback path). For tests of the fallback.
void set_anonymous_temp_files(bool enabled);

/// Ignores SIGXFSZ process-wide when it has its default action (idempotent), so that a file-size
/// limit (`ulimit -f`) surfaces as an EFBIG write error instead of killing the process.
void ignore_file_size_signal();

/// strerror(err) for a work file that could not be created or written; a full folder (ENOSPC,
/// EDQUOT) or a file size limit (EFBIG) gets the way out: "...: free space or choose another
/// with --work-dir".
std::string work_file_problem(int err);

/// Removes every live temporary file of this process. Async-signal-safe (only unlinkat over a
/// fixed registry), for applications that install their own signal handlers.
void remove_temp_files_now() noexcept;

}  // namespace streamcvd
