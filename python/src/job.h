// Running a library job from Python: off the GIL, on a worker thread, while the calling thread
// watches for Ctrl-C. An interrupt sets the job's cancel flag, which its progress callback turns
// into an exception (core/mesh/progress.h: the job unwinds, its temporary files vanish, no output is
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

#include "streamcvd/core/mesh/progress.h"
#include "python/src/arrays.h"
#include "streamcvd/streaming/run_reports.h"

namespace streamcvd::python {

/// The cancel flag of one job and the progress callback that obeys it (feeding `io_log`, the
/// report's io.stages, too, and the caller's `progress` callable if any).
struct JobControl {
  std::atomic<bool> cancel{false};
  StageIoLog io_log;
  std::mutex io_mutex;  // reports may come from the reading and the building thread at once
  py::object progress = py::none();  ///< the caller's progress=: called with a dict per report
  std::optional<py::error_already_set> progress_error;  ///< what it raised: re-raised by the caller

  /// `progress` (None or a callable) checked and kept for callback().
  explicit JobControl(py::object progress_callable = py::none()) : progress(std::move(progress_callable)) {
    if (!progress.is_none() && !PyCallable_Check(progress.ptr()))
      throw py::type_error("progress: expected None or a callable taking one dict, got " +
                           std::string(py::str(progress.get_type())));
  }

  ProgressCallback callback() {
    return [this](const StageProgress& p) {
      {
        std::lock_guard lock(io_mutex);
        io_log.see(p);
      }
      if (cancel.load(std::memory_order_relaxed)) throw Cancelled{};
      if (!progress.is_none()) call_progress(p);
    };
  }

 private:
  // Runs the caller's callable under the GIL (the calling thread waits without it); an
  // exception it raises cancels the job and is raised again by run_interruptible.
  void call_progress(const StageProgress& p) {
    py::gil_scoped_acquire gil;
    // Checked again with the GIL: a Ctrl-C handled while this thread waited for it has set the
    // flag, and the callable must not see a report of the job it stopped.
    if (cancel.load(std::memory_order_relaxed)) throw Cancelled{};
    try {
      py::dict d;
      d["stage"] = p.stage;
      d["done"] = p.done;
      d["total"] = p.total;
      d["unit"] = p.unit;
      d["round"] = p.round;
      if (p.fraction >= 0) d["fraction"] = p.fraction;
      else if (p.total > 0) d["fraction"] = double(p.done) / double(p.total);
      else d["fraction"] = py::none();  // a size not known up front (a pipe, an OBJ)
      d["finished"] = p.finished;
      progress(d);
    } catch (py::error_already_set& e) {
      if (!progress_error) progress_error.emplace(std::move(e));
      cancel = true;
      throw Cancelled{};
    }
  }
};

/// Runs `work()` on a worker thread without the GIL and returns its result, or rethrows its
/// exception (or what the progress callable raised). Every 20 ms the calling thread checks for
/// signals (PyErr_CheckSignals, so Ctrl-C and Python signal handlers work during the job): on
/// one, it sets control.cancel, waits for the job to unwind and raises the signal's exception
/// (KeyboardInterrupt).
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
  if (control.progress_error) throw std::move(*control.progress_error);
  if (error) std::rethrow_exception(error);
  return std::move(*result);
}

}  // namespace streamcvd::python
