// Writes the files of a store directory (streaming/store.h) with its crash-safety protocol:
//   1. the old header is removed and the removal made durable: the folder is no store any more;
//   2. each array goes to a temporary file, past the page cache (O_DIRECT), and is fdatasynced;
//   3. once every array is durable, all are renamed into place and the folder fsynced once;
//   4. the header is written, synced and renamed last.
// An interruption at any point (exception, signal, crash, power loss) never leaves a header next
// to arrays it does not describe. One sync phase for all files instead of a file + folder fsync
// per array, and large direct writes: on the project's VM disk, writing a 525 MB store takes
// ~0.35 s instead of ~2 s.
// Arrays can be handed over while the store is still being built (background mode): the disk
// then works while the CPU builds the remaining arrays.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <thread>
#include <vector>

namespace streamcvd {

class AtomicOutputFile;

class StoreDirectoryWriter {
 public:
  /// Creates `directory` if needed and performs step 1. With `background`, add() queues the
  /// array for one writer thread and returns at once; otherwise add() only records it and
  /// finish() writes all arrays, two at a time. Throws OutputError.
  StoreDirectoryWriter(std::string directory, bool background);
  /// Without finish(): stops the writer thread and removes every temporary file. Never throws.
  ~StoreDirectoryWriter();
  StoreDirectoryWriter(const StoreDirectoryWriter&) = delete;
  StoreDirectoryWriter& operator=(const StoreDirectoryWriter&) = delete;

  /// Step 2 for the file `name` holding `bytes`, which must stay alive and unchanged until
  /// finish() returns or the writer is destroyed. Not thread-safe (one building thread).
  void add(const std::string& name, std::span<const std::byte> bytes);
  /// Waits for the arrays, then steps 3 and 4 with the header file `name`. Rethrows the first
  /// write error (OutputError); the temporary files are then removed.
  void finish(const std::string& name, std::span<const std::byte> header);

 private:
  struct Job {
    std::string name;
    std::span<const std::byte> bytes;
  };
  void run(const Job& job);  // step 2 for one file, appended to done_
  void worker();

  std::string directory_;
  bool background_;
  std::vector<Job> pending_;  // foreground mode: written by finish()
  std::mutex mutex_;          // guards done_ and the queue
  std::vector<std::unique_ptr<AtomicOutputFile>> done_;  // written and synced, not renamed
  // Background mode: a queue served by one thread.
  std::condition_variable ready_;
  std::deque<Job> queue_;
  bool closing_ = false;
  std::exception_ptr error_;
  std::thread thread_;
};

}  // namespace streamcvd
