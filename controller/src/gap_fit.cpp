#include "hil/ctl/gap_fit.hpp"

#include <algorithm>
#include <cmath>

#include "hil/physics.hpp"

namespace hil::ctl {

double GapFit::cost(const Window& w, double extreme_rad, int dir, std::int64_t skip, double gap_rad, double* rms,
                    double* excursion) const noexcept {
  const double half = gap_rad / 2;
  // The old flank pushed in -dir: valve = motor + dir*half while in contact. Before the extreme
  // the motor still pushed; from the extreme on the valve holds at the extreme's contact angle.
  double valve = w.extreme >= 0 ? w.motor_rad[0] + dir * half : extreme_rad + dir * half;
  double lp1 = valve, lp2 = valve;
  double sum = 0, sum2 = 0;
  double lo = 1e300, hi = -1e300;
  std::int64_t n = 0;
  for (std::int64_t i = 0; i < w.n; ++i) {
    const double m = w.motor_rad[static_cast<std::size_t>(i)];
    valve = physics::play_rad(valve, m, half);
    lp1 += alpha_ * (valve - lp1);
    lp2 += alpha_ * (lp1 - lp2);
    if (i >= skip) {
      const double r = w.valve_eq_rad[static_cast<std::size_t>(i)] - lp2;
      sum += r;
      sum2 += r * r;
      lo = std::min(lo, lp2);
      hi = std::max(hi, lp2);
      ++n;
    }
  }
  if (n == 0) return 0;
  const double c = sum2 - sum * sum / static_cast<double>(n);  // the best constant offset removed
  if (rms) *rms = std::sqrt(std::max(c, 0.0) / static_cast<double>(n));
  if (excursion) *excursion = hi - lo;
  return c;
}

template <int K>
void GapFit::costs(const Window& w, double extreme_rad, int dir, std::int64_t skip, const double* gap_rad,
                   double* cost_out) const noexcept {
  // cost() for K gaps at once, lane by lane the same operations in the same order (so the same
  // numbers): one gap's samples form a chain of dependent low-pass updates, K of them side by side
  // keep the FPU busy instead of waiting on each.
  double half[K], valve[K], lp1[K], lp2[K], sum[K], sum2[K];
  for (int j = 0; j < K; ++j) {
    half[j] = gap_rad[j] / 2;
    valve[j] = w.extreme >= 0 ? w.motor_rad[0] + dir * half[j] : extreme_rad + dir * half[j];
    lp1[j] = lp2[j] = valve[j];
    sum[j] = sum2[j] = 0;
  }
  const double alpha = alpha_;
  for (std::int64_t i = 0; i < w.n; ++i) {
    const double m = w.motor_rad[static_cast<std::size_t>(i)];
    for (int j = 0; j < K; ++j) {
      valve[j] = physics::play_rad(valve[j], m, half[j]);
      lp1[j] += alpha * (valve[j] - lp1[j]);
      lp2[j] += alpha * (lp1[j] - lp2[j]);
    }
    if (i >= skip) {
      const double eq = w.valve_eq_rad[static_cast<std::size_t>(i)];
      for (int j = 0; j < K; ++j) {
        const double r = eq - lp2[j];
        sum[j] += r;
        sum2[j] += r * r;
      }
    }
  }
  const std::int64_t n = std::max<std::int64_t>(w.n - std::max<std::int64_t>(skip, 0), 0);
  for (int j = 0; j < K; ++j) cost_out[j] = n == 0 ? 0 : sum2[j] - sum[j] * sum[j] / static_cast<double>(n);
}

GapFit::Result GapFit::fit(History& h, std::int64_t extreme, double extreme_rad, int dir, std::int64_t lead,
                           std::int64_t skip) const noexcept {
  Result out;
  const std::int64_t to = h.count - 1;
  // The window starts `lead` samples before the extreme, but never before the first sample
  // pushed (a reversal within the first `lead` samples of a run), nor before the oldest sample
  // the ring still holds, nor so early that it exceeds kMaxWindow.
  std::int64_t from = std::max(extreme - lead, to - kMaxWindow + 1);
  from = std::max({from, h.count - kCapacity, std::int64_t{0}});
  if (to - from <= skip + 10 || dir == 0) return out;
  Window& w = h.scratch;
  w.n = to - from + 1;
  w.extreme = extreme - from;
  for (std::int64_t i = 0; i < w.n; ++i) {
    const auto slot = static_cast<std::size_t>((from + i) % kCapacity);
    w.motor_rad[static_cast<std::size_t>(i)] = h.motor_rad[slot];
    w.valve_eq_rad[static_cast<std::size_t>(i)] = h.valve_eq_rad[slot];
  }
  // Coarse grid, then golden section around the best cell.
  constexpr int kGrid = 24;
  double best = 0, best_cost = 1e300;
  constexpr int kLanes = 5;
  static_assert((kGrid + 1) % kLanes == 0);
  for (int i0 = 0; i0 <= kGrid; i0 += kLanes) {
    double g[kLanes], c[kLanes];
    for (int j = 0; j < kLanes; ++j) g[j] = gap_max_rad_ * (i0 + j) / kGrid;
    costs<kLanes>(w, extreme_rad, dir, skip, g, c);
    for (int j = 0; j < kLanes; ++j)
      if (c[j] < best_cost) best_cost = c[j], best = g[j];
  }
  const double cell = gap_max_rad_ / kGrid;
  double a = std::max(best - cell, 0.0), b = std::min(best + cell, gap_max_rad_);
  constexpr double kInvPhi = 0.6180339887498949;
  // Golden section, two iterations per pass: the point the first one evaluates and both points
  // the second may evaluate (which one depends on the first's cost) go through costs<3>
  // together; the sequence of points and costs is the one-at-a-time search's.
  struct Golden {
    double a, b, x1, x2, f1, f2;
  };
  // One iteration's interval and points; the new point's cost (f1 going left, f2 going right) is
  // the caller's to fill in.
  auto advance = [](Golden g, bool left) noexcept {
    if (left) {
      g.b = g.x2, g.x2 = g.x1, g.f2 = g.f1;
      g.x1 = g.b - kInvPhi * (g.b - g.a);
    } else {
      g.a = g.x1, g.x1 = g.x2, g.f1 = g.f2;
      g.x2 = g.a + kInvPhi * (g.b - g.a);
    }
    return g;
  };
  Golden g{a, b, b - kInvPhi * (b - a), a + kInvPhi * (b - a), 0, 0};
  {
    const double x[2] = {g.x1, g.x2};
    double f[2];
    costs<2>(w, extreme_rad, dir, skip, x, f);
    g.f1 = f[0], g.f2 = f[1];
  }
  for (int it = 0; it < 18; it += 2) {  // the cell shrinks to 1e-4 of itself
    const bool left = g.f1 < g.f2;
    Golden g1 = advance(g, left);
    const double x[3] = {left ? g1.x1 : g1.x2, advance(g1, true).x1, advance(g1, false).x2};
    double f[3];
    costs<3>(w, extreme_rad, dir, skip, x, f);
    (left ? g1.f1 : g1.f2) = f[0];
    const bool left2 = g1.f1 < g1.f2;
    g = advance(g1, left2);
    (left2 ? g.f1 : g.f2) = left2 ? f[1] : f[2];
  }
  a = g.a, b = g.b;
  out.gap_rad = 0.5 * (a + b);
  cost(w, extreme_rad, dir, skip, out.gap_rad, &out.rms_rad, &out.excursion_rad);
  // A best fit at the edge of the search range, or one whose valve barely moved, is no measurement.
  out.ok =
      out.gap_rad > 0.5 * cell && out.gap_rad < gap_max_rad_ - 0.5 * cell && out.excursion_rad >= kMinExcursion * out.rms_rad;
  return out;
}

}  // namespace hil::ctl
