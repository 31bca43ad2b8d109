// The work space of a job (DESIGN.md §3): where the arrays sized by the input live. In RAM while
// they fit the job's budget; beyond it in anonymous files of the work folder, mapped read-write
// and touched chunk by chunk, so their pages are page cache that the kernel writes back and
// reclaims under a memory limit. Files are created with O_TMPFILE (or unlinked at once) and their
// blocks reserved up front: nothing is left behind whatever ends the process, and a full disk is
// an OutputError at allocation, never a SIGBUS later.
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "streamcvd/core/mesh/large_array.h"

namespace streamcvd {

class WorkSpace final : public ArrayStorage {
 public:
  /// Hot arrays go to RAM while the RAM ones total at most `ram_budget` bytes, cold ones while
  /// they total at most half of it; the rest to files in `folder` ("" = TMPDIR, else /tmp).
  /// ram_budget = ~0 keeps everything in RAM.
  WorkSpace(std::string folder, uint64_t ram_budget);
  ~WorkSpace() override = default;

  /// Throws OutputError "<folder>: cannot create a work file ... : <reason>" (disk full, file
  /// size limit, no such folder).
  void* allocate(size_t bytes, const char* name, ArrayUse use) override;
  void release(void* data, size_t bytes) noexcept override;
  void will_need(const void* data, size_t bytes) override;
  void dont_need(const void* data, size_t bytes) override;

  /// The file-backed arrays of exactly V·s bytes (s = 1..256): the per-vertex work arrays a
  /// chunk scheduler advises by vertex range. (address, bytes); thread-safe.
  std::vector<std::pair<const void*, size_t>> file_regions(uint32_t V) const;

  const std::string& folder() const { return folder_; }
  uint64_t ram_bytes() const { return ram_.load(); }
  uint64_t file_bytes() const { return files_.load(); }
  /// Largest total of file-backed bytes at once (what the work folder had to hold).
  uint64_t peak_file_bytes() const { return peak_files_.load(); }

 private:
  std::string folder_;
  uint64_t ram_budget_;
  std::atomic<uint64_t> ram_{0}, files_{0}, peak_files_{0};
  mutable std::mutex mutex_;
  std::map<const void*, size_t> file_regions_;  // file-backed arrays by address
};

}  // namespace streamcvd
