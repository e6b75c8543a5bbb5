// A signal programmed over time: piecewise linear between breakpoints (two breakpoints at the
// same time make a jump), plus optional sine overlays. Used for the pressure reference and for
// the programmed gap. Evaluation with a cursor is real-time safe for increasing times.
#pragma once

#include <cstddef>
#include <limits>
#include <vector>

namespace hil::bench {

struct Breakpoint {
  double t_s;
  double value;
};

struct SineOverlay {
  double from_s, to_s, amplitude, period_s;
};

class Schedule {
 public:
  Schedule() = default;
  explicit Schedule(double initial) : initial_(initial) {}

  void add(double t_s, double value) { points_.push_back({t_s, value}); }
  void add_sine(const SineOverlay& s) { sines_.push_back(s); }

  // Random access, O(log n).
  double at(double t_s) const noexcept;
  // For increasing times: O(1) amortised, no allocation. Real-time safe.
  struct Cursor {
    std::size_t next = 0;
    // The level the schedule holds over [level_from_s, level_until_s), where the last evaluation
    // found one (a step profile between its steps, no sine): most periods of a run return it
    // without a search. Empty until then.
    double level_from_s = std::numeric_limits<double>::infinity();
    double level_until_s = -std::numeric_limits<double>::infinity();
    double level = 0;
  };
  double at(double t_s, Cursor& cursor) const noexcept {
    if (t_s >= cursor.level_from_s && t_s < cursor.level_until_s) return cursor.level;
    return at_searched(t_s, cursor);
  }

  double initial() const { return initial_; }
  const std::vector<Breakpoint>& points() const { return points_; }
  const std::vector<SineOverlay>& sines() const { return sines_; }
  // Every value the piecewise-linear part takes at a breakpoint (the extremes of that part).
  double last_level() const { return points_.empty() ? initial_ : points_.back().value; }

 private:
  double at_searched(double t_s, Cursor& cursor) const noexcept;  // at() past the cursor's level
  double base_between(std::size_t next, double t_s) const noexcept;
  double sines_at(double t_s) const noexcept;
  double initial_ = 0;
  std::vector<Breakpoint> points_;
  std::vector<SineOverlay> sines_;
};

// Times at which the schedule reverses direction (its first movement counts as a reversal):
// sampled every period_s, a reversal is declared once the signal has retreated more than
// hysteresis from its extreme; the reported time is when the extreme was left.
std::vector<double> reversal_times(const Schedule& s, double duration_s, double period_s, double hysteresis);

// How many separate moves (a step, a ramp) the schedule makes, in either direction.
long move_count(const Schedule& s, double duration_s, double period_s);

}  // namespace hil::bench
