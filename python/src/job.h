// Running a library job from Python: off the GIL, on a worker thread, while the calling thread
// watches for Ctrl-C. An interrupt sets the job's cancel flag, which its progress callback turns
// into an exception (core/progress.h: the job unwinds, its temporary files vanish, no output is
// renamed into place); the caller then gets KeyboardInterrupt.
#pragma once

#include <pybind11/pybind11.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include "core/progress.h"
#include "python/src/arrays.h"
#include "streaming/run_reports.h"

namespace streamcvd::python {

/// The cancel flag of one job and the progress callback that obeys it (feeding `io_log`, the
/// report's io.stages, too).
struct JobControl {
  std::atomic<bool> cancel{false};
  StageIoLog io_log;
  std::mutex io_mutex;  // reports may come from the reading and the building thread at once

  ProgressCallback callback() {
    return [this](const StageProgress& p) {
      {
        std::lock_guard lock(io_mutex);
        io_log.see(p);
      }
      if (cancel.load(std::memory_order_relaxed)) throw Cancelled{};
    };
  }
};

/// Runs `work()` on a worker thread without the GIL and returns its result, or rethrows its
/// exception. Every 20 ms the calling thread checks for signals (PyErr_CheckSignals, so Ctrl-C
/// and Python signal handlers work during the job): on one, it sets control.cancel, waits for
/// the job to unwind and raises the signal's exception (KeyboardInterrupt).
template <class Work>
auto run_interruptible(JobControl& control, Work&& work) -> decltype(work()) {
  std::optional<decltype(work())> result;
  std::exception_ptr error;
  std::mutex mutex;
  std::condition_variable finished;
  bool done = false;
  std::thread worker([&] {
    try {
      result.emplace(work());
    } catch (...) {
      error = std::current_exception();
    }
    std::lock_guard lock(mutex);
    done = true;
    finished.notify_all();
  });
  bool interrupted = false;
  for (;;) {
    bool over = false;
    {
      py::gil_scoped_release release;
      std::unique_lock lock(mutex);
      over = finished.wait_for(lock, std::chrono::milliseconds(20), [&] { return done; });
    }
    if (over) break;
    if (!interrupted && PyErr_CheckSignals() != 0) {  // the exception is set: raised once the job is gone
      interrupted = true;
      control.cancel = true;
    }
  }
  {
    py::gil_scoped_release release;
    worker.join();
  }
  if (interrupted) throw py::error_already_set();
  if (error) std::rethrow_exception(error);
  return std::move(*result);
}

}  // namespace streamcvd::python
