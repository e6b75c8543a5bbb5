#include "hil/bench/rt/schedule.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace hil::bench {

double Schedule::sines_at(double t_s) const noexcept {
  double sum = 0;
  for (const auto& s : sines_) {
    if (t_s >= s.from_s && t_s < s.to_s) sum += s.amplitude * std::sin(2 * std::numbers::pi * (t_s - s.from_s) / s.period_s);
  }
  return sum;
}

double Schedule::base_between(std::size_t next, double t_s) const noexcept {
  // `next` is the first breakpoint later than t_s.
  if (next == 0) return points_.empty() ? initial_ : (t_s < points_[0].t_s ? initial_ : points_[0].value);
  const Breakpoint& a = points_[next - 1];
  if (next == points_.size()) return a.value;
  const Breakpoint& b = points_[next];
  // A level between two breakpoints (every step profile, most of the time) needs no division;
  // the interpolation would give a.value too (plus a zero).
  if (b.value == a.value) return a.value;
  return a.value + (b.value - a.value) * (t_s - a.t_s) / (b.t_s - a.t_s);
}

double Schedule::at(double t_s) const noexcept {
  const auto it = std::upper_bound(points_.begin(), points_.end(), t_s, [](double t, const Breakpoint& p) { return t < p.t_s; });
  // Before the first breakpoint the signal holds its initial value.
  const std::size_t next = static_cast<std::size_t>(it - points_.begin());
  const double base = next == 0 ? initial_ : base_between(next, t_s);
  return base + sines_at(t_s);
}

double Schedule::at_searched(double t_s, Cursor& c) const noexcept {
  if (c.next > 0 && t_s < points_[c.next - 1].t_s) c.next = 0;  // went back in time: restart
  while (c.next < points_.size() && points_[c.next].t_s <= t_s) ++c.next;
  const double base = c.next == 0 ? initial_ : base_between(c.next, t_s);
  const double value = base + (sines_.empty() ? 0.0 : sines_at(t_s));
  // Keep the level for the calls to come when the value holds until the next breakpoint: every
  // time in [from, until) finds the same `next` and the same value (the same bits: + 0.0 too).
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const bool level =
      sines_.empty() && (c.next == 0 || c.next == points_.size() || points_[c.next].value == points_[c.next - 1].value);
  c.level_from_s = level ? (c.next == 0 ? -kInf : points_[c.next - 1].t_s) : kInf;
  c.level_until_s = level ? (c.next == points_.size() ? kInf : points_[c.next].t_s) : -kInf;
  c.level = value;
  return value;
}

std::vector<double> reversal_times(const Schedule& s, double duration_s, double period_s, double hysteresis) {
  std::vector<double> out;
  Schedule::Cursor cursor;
  double extreme = s.at(0.0, cursor), extreme_t = 0.0;
  int dir = 0;
  const auto n = static_cast<long>(std::floor(duration_s / period_s + 1e-9));
  for (long k = 1; k <= n; ++k) {
    const double t = k * period_s;
    const double v = s.at(t, cursor);
    if (dir == 0) {  // not moved yet: the first movement beyond the hysteresis is reversal 1
      if (std::abs(v - extreme) > hysteresis) {
        out.push_back(extreme_t + period_s);
        dir = v > extreme ? 1 : -1;
        extreme = v;
        extreme_t = t;
      } else if (v == extreme) {
        extreme_t = t;
      }
    } else if (dir * (v - extreme) >= 0) {  // moving on (or resting) in the same direction
      extreme = v;
      extreme_t = t;
    } else if (dir * (extreme - v) > hysteresis) {  // turned back: the first sample that left
      out.push_back(extreme_t + period_s);
      dir = -dir;
      extreme = v;
      extreme_t = t;
    }
  }
  return out;
}

long move_count(const Schedule& s, double duration_s, double period_s) {
  Schedule::Cursor cursor;
  double prev = s.at(0.0, cursor);
  int was = 0;  // direction of the previous sample's change, 0 = resting
  long moves = 0;
  const auto n = static_cast<long>(std::floor(duration_s / period_s + 1e-9));
  for (long k = 1; k <= n; ++k) {
    const double v = s.at(k * period_s, cursor);
    const double d = v - prev;
    const int now = std::abs(d) <= 1e-9 * (1 + std::abs(v)) ? 0 : (d > 0 ? 1 : -1);
    if (now != 0 && now != was) ++moves;
    was = now;
    prev = v;
  }
  return moves;
}

}  // namespace hil::bench
