//! Named per-phase wall-clock timers (scoped), reported at the end of a run.
#pragma once

#include <chrono>
#include <map>
#include <string>

namespace gen4d {

class PhaseTimers {
 public:
  void add(const std::string& phase, double seconds) { totals_[phase] += seconds; }
  double total(const std::string& phase) const {
    auto it = totals_.find(phase);
    return it == totals_.end() ? 0.0 : it->second;
  }
  const std::map<std::string, double>& totals() const { return totals_; }

  //! Adds the lifetime of the scope to `phase`.
  class Scope {
   public:
    Scope(PhaseTimers& t, const char* phase)
        : t_(t), phase_(phase), start_(std::chrono::steady_clock::now()) {}
    ~Scope() {
      t_.add(phase_,
             std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count());
    }
    Scope(const Scope&) = delete;
    Scope& operator=(const Scope&) = delete;

   private:
    PhaseTimers& t_;
    const char* phase_;
    std::chrono::steady_clock::time_point start_;
  };

 private:
  std::map<std::string, double> totals_;
};

}  // namespace gen4d
