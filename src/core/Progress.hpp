//! Rank-0 progress lines for long runs: step, simulated time, steps/s, ETA and solver effort.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "core/Log.hpp"

namespace gen4d {

//! Accumulates per-step solver effort and prints one line every `interval` wall seconds
//! (and at the last step). Every rank may call it; only rank 0 prints.
class ProgressLog {
 public:
  using Clock = std::chrono::steady_clock;

  ProgressLog(long first_step, long total_steps, double interval)
      : first_(first_step), total_(total_steps), interval_(interval) {}

  //! Records one step's outer loops (extra ones included), sweeps and true residual.
  void record(int loops, long sweeps, double residual, bool accurate) {
    ++steps_;
    loops_ += loops;
    sweeps_ += static_cast<double>(sweeps);
    worst_ = std::max(worst_, residual);
    inaccurate_ += accurate ? 0 : 1;
  }

  void maybe_print(long step, double time) {
    if (seconds_since(last_) < interval_ && step != total_) return;
    last_ = Clock::now();
    const double rate = static_cast<double>(step - first_) / std::max(elapsed(), 1e-9);
    log::info(
        "step {:>6}/{}  t = {:.4f} s  {:.2f} steps/s  ETA {}  loops {:.1f}  sweeps {:.0f}  "
        "worst residual {:.1e}",
        step, total_, time, rate,
        format_duration(static_cast<double>(total_ - step) / std::max(rate, 1e-12)),
        loops_ / std::max(1L, steps_), sweeps_ / std::max(1L, steps_), worst_);
  }

  double elapsed() const { return seconds_since(start_); }
  long steps() const { return steps_; }
  long inaccurate_steps() const { return inaccurate_; }
  double worst_residual() const { return worst_; }

  static std::string format_duration(double s) {
    if (!std::isfinite(s)) return "?";
    if (s < 120) return fmt::format("{:.0f} s", s);
    if (s < 7200) return fmt::format("{:.1f} min", s / 60);
    return fmt::format("{:.1f} h", s / 3600);
  }

 private:
  static double seconds_since(Clock::time_point t) {
    return std::chrono::duration<double>(Clock::now() - t).count();
  }

  long first_, total_;
  double interval_;
  Clock::time_point start_ = Clock::now(), last_ = Clock::now();
  long steps_ = 0, inaccurate_ = 0;
  double loops_ = 0, sweeps_ = 0, worst_ = 0;
};

}  // namespace gen4d
