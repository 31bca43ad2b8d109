// Wall-clock timing of stages for the reports: the one clock and conversion every stage uses.
#pragma once

#include <chrono>

namespace streamcvd {

/// Seconds elapsed since `t0` on the steady clock (wall time, not CPU). Thread-safe.
inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace streamcvd
