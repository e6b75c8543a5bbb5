#include "hil/ctl/gap_fit.hpp"

#include <algorithm>
#include <cmath>

namespace hil::ctl {

double GapFit::cost(const History& h, std::int64_t from, std::int64_t to, std::int64_t extreme, double extreme_rad,
                    int dir, std::int64_t skip, double gap_rad, double* rms) const noexcept {
  const double half = gap_rad / 2;
  auto at = [&](const std::array<double, kCapacity>& a, std::int64_t i) { return a[static_cast<std::size_t>(i % kCapacity)]; };
  // The old flank pushed in -dir: valve = motor + dir*half while in contact. Before the extreme
  // the motor still pushed; from the extreme on the valve holds at the extreme's contact angle.
  double valve = from <= extreme ? at(h.motor_rad, from) + dir * half : extreme_rad + dir * half;
  double lp1 = valve, lp2 = valve;
  double sum = 0, sum2 = 0;
  std::int64_t n = 0;
  for (std::int64_t i = from; i <= to; ++i) {
    const double m = at(h.motor_rad, i);
    if (m - half > valve) {
      valve = m - half;
    } else if (m + half < valve) {
      valve = m + half;
    }
    lp1 += alpha_ * (valve - lp1);
    lp2 += alpha_ * (lp1 - lp2);
    if (i - from >= skip) {
      const double r = at(h.valve_eq_rad, i) - lp2;
      sum += r;
      sum2 += r * r;
      ++n;
    }
  }
  if (n == 0) return 0;
  const double c = sum2 - sum * sum / static_cast<double>(n);  // the best constant offset removed
  if (rms) *rms = std::sqrt(std::max(c, 0.0) / static_cast<double>(n));
  return c;
}

GapFit::Result GapFit::fit(const History& h, std::int64_t extreme, double extreme_rad, int dir, std::int64_t lead,
                           std::int64_t skip) const noexcept {
  Result out;
  const std::int64_t to = h.count - 1;
  std::int64_t from = std::max(extreme - lead, to - kMaxWindow + 1);
  from = std::max(from, h.count - kCapacity);
  if (to - from <= skip + 10 || dir == 0) return out;
  // Coarse grid, then golden section around the best cell.
  constexpr int kGrid = 24;
  double best = 0, best_cost = 1e300;
  for (int i = 0; i <= kGrid; ++i) {
    const double g = gap_max_rad_ * i / kGrid;
    const double c = cost(h, from, to, extreme, extreme_rad, dir, skip, g, nullptr);
    if (c < best_cost) best_cost = c, best = g;
  }
  const double cell = gap_max_rad_ / kGrid;
  double a = std::max(best - cell, 0.0), b = std::min(best + cell, gap_max_rad_);
  constexpr double kInvPhi = 0.6180339887498949;
  double x1 = b - kInvPhi * (b - a), x2 = a + kInvPhi * (b - a);
  double f1 = cost(h, from, to, extreme, extreme_rad, dir, skip, x1, nullptr);
  double f2 = cost(h, from, to, extreme, extreme_rad, dir, skip, x2, nullptr);
  for (int it = 0; it < 24; ++it) {
    if (f1 < f2) {
      b = x2, x2 = x1, f2 = f1;
      x1 = b - kInvPhi * (b - a);
      f1 = cost(h, from, to, extreme, extreme_rad, dir, skip, x1, nullptr);
    } else {
      a = x1, x1 = x2, f1 = f2;
      x2 = a + kInvPhi * (b - a);
      f2 = cost(h, from, to, extreme, extreme_rad, dir, skip, x2, nullptr);
    }
  }
  out.gap_rad = 0.5 * (a + b);
  cost(h, from, to, extreme, extreme_rad, dir, skip, out.gap_rad, &out.rms_rad);
  // A best fit at the edge of the search range is no measurement.
  out.ok = out.gap_rad > 0.5 * cell && out.gap_rad < gap_max_rad_ - 0.5 * cell;
  return out;
}

}  // namespace hil::ctl
