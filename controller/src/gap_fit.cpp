#include "hil/ctl/gap_fit.hpp"

#include <algorithm>
#include <atomic>
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

namespace {

// K gaps' costs side by side, in vectors V of kWidth doubles: one gap's samples form a chain of
// dependent low-pass updates, and K of them side by side keep the FPU busy instead of waiting on
// each. Lane by lane these are cost()'s IEEE operations in the same order, so every vector width
// gives the same bits (the play operator, physics::play_in_place, is branch-free for that). A K
// that is no multiple of the width repeats its last gap in the spare lanes. The vectors are
// GCC/Clang vector extensions: SSE2 or AVX2 registers on x86-64, whatever the target has elsewhere.
template <int K, class V>
[[gnu::always_inline]] inline void cost_lanes(const GapFit::Window& w, double alpha_1, double extreme_rad, int dir,
                                              std::int64_t skip, const double* gap_rad, double* cost_out) noexcept {
  constexpr int kWidth = sizeof(V) / sizeof(double);
  constexpr int kVectors = (K + kWidth - 1) / kWidth;
  V half[kVectors], valve[kVectors], lp1[kVectors], lp2[kVectors], sum[kVectors], sum2[kVectors], alpha;
  const double start = w.extreme >= 0 ? w.motor_rad[0] : extreme_rad;
  const double d = dir;
  for (int l = 0; l < kWidth; ++l) alpha[l] = alpha_1;
  for (int v = 0; v < kVectors; ++v) {
    for (int l = 0; l < kWidth; ++l) {
      half[v][l] = gap_rad[std::min(kWidth * v + l, K - 1)] / 2;
      valve[v][l] = start + d * half[v][l];
      sum[v][l] = sum2[v][l] = 0;
    }
    lp1[v] = lp2[v] = valve[v];
  }
  for (std::int64_t i = 0; i < w.n; ++i) {
    V m;
    for (int l = 0; l < kWidth; ++l) m[l] = w.motor_rad[static_cast<std::size_t>(i)];
    for (int v = 0; v < kVectors; ++v) {
      physics::play_in_place(valve[v], m, half[v]);
      lp1[v] += alpha * (valve[v] - lp1[v]);
      lp2[v] += alpha * (lp1[v] - lp2[v]);
    }
    if (i >= skip) {
      V eq;
      for (int l = 0; l < kWidth; ++l) eq[l] = w.valve_eq_rad[static_cast<std::size_t>(i)];
      for (int v = 0; v < kVectors; ++v) {
        const V r = eq - lp2[v];
        sum[v] += r;
        sum2[v] += r * r;
      }
    }
  }
  const std::int64_t n = std::max<std::int64_t>(w.n - std::max<std::int64_t>(skip, 0), 0);
  for (int j = 0; j < K; ++j) {
    const double s = sum[j / kWidth][j % kWidth], s2 = sum2[j / kWidth][j % kWidth];
    cost_out[j] = n == 0 ? 0 : s2 - s * s / static_cast<double>(n);
  }
}

using Pair = double __attribute__((vector_size(16)));  // SSE2: every x86-64

#if defined(__x86_64__)
using Quad = double __attribute__((vector_size(32)));

template <int K>
[[gnu::target("avx2")]] void cost_lanes_avx2(const GapFit::Window& w, double alpha, double extreme_rad, int dir,
                                             std::int64_t skip, const double* gap_rad, double* cost_out) noexcept {
  cost_lanes<K, Quad>(w, alpha, extreme_rad, dir, skip, gap_rad, cost_out);
}

bool cpu_has_avx2() noexcept { return __builtin_cpu_supports("avx2"); }
#else
bool cpu_has_avx2() noexcept { return false; }
#endif

std::atomic<bool> g_wide_lanes{cpu_has_avx2()};

}  // namespace

bool GapFit::use_wide_lanes(bool wanted) noexcept {
  g_wide_lanes.store(wanted && cpu_has_avx2(), std::memory_order_relaxed);
  return g_wide_lanes.load(std::memory_order_relaxed);
}

template <int K>
void GapFit::costs(const Window& w, double extreme_rad, int dir, std::int64_t skip, const double* gap_rad,
                   double* cost_out) const noexcept {
#if defined(__x86_64__)
  if (g_wide_lanes.load(std::memory_order_relaxed))
    return cost_lanes_avx2<K>(w, alpha_, extreme_rad, dir, skip, gap_rad, cost_out);
#endif
  cost_lanes<K, Pair>(w, alpha_, extreme_rad, dir, skip, gap_rad, cost_out);
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
    const std::size_t at = slot(from + i);
    w.motor_rad[static_cast<std::size_t>(i)] = h.motor_rad[at];
    w.valve_eq_rad[static_cast<std::size_t>(i)] = h.valve_eq_rad[at];
  }
  // Coarse grid (all its points in one pass), then golden section around the best cell.
  constexpr int kGrid = 24;
  double best = 0, best_cost = 1e300;
  {
    double g[kGrid + 1], c[kGrid + 1];
    for (int i = 0; i <= kGrid; ++i) g[i] = gap_max_rad_ * i / kGrid;
    costs<kGrid + 1>(w, extreme_rad, dir, skip, g, c);
    for (int i = 0; i <= kGrid; ++i)
      if (c[i] < best_cost) best_cost = c[i], best = g[i];
  }
  const double cell = gap_max_rad_ / kGrid;
  double a = std::max(best - cell, 0.0), b = std::min(best + cell, gap_max_rad_);
  constexpr double kInvPhi = 0.6180339887498949;
  // Golden section, three iterations per pass: the point the first one evaluates, both points
  // the second may evaluate (which one depends on the first's cost) and the four the third may
  // go through costs<7> together; the sequence of points and costs is the one-at-a-time
  // search's.
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
  // The pass's possible iterations as a tree in breadth-first order: node 0 is the first
  // iteration (its direction is known), node j's children 2j+1 and 2j+2 go left and right after it.
  constexpr int kDepth = 3, kNodes = (1 << kDepth) - 1, kIterations = 18;  // the cell shrinks to 1e-4 of itself
  static_assert(kIterations % kDepth == 0);
  for (int it = 0; it < kIterations; it += kDepth) {
    const bool left = g.f1 < g.f2;
    Golden node[kNodes];
    double x[kNodes], f[kNodes];
    node[0] = advance(g, left);
    x[0] = left ? node[0].x1 : node[0].x2;
    for (int j = 1; j < kNodes; ++j) {
      const bool goes_left = j % 2 == 1;
      node[j] = advance(node[(j - 1) / 2], goes_left);
      x[j] = goes_left ? node[j].x1 : node[j].x2;
    }
    costs<kNodes>(w, extreme_rad, dir, skip, x, f);
    g = node[0];
    (left ? g.f1 : g.f2) = f[0];
    for (int j = 0, level = 1; level < kDepth; ++level) {
      const bool l = g.f1 < g.f2;
      j = 2 * j + (l ? 1 : 2);
      g = advance(g, l);
      (l ? g.f1 : g.f2) = f[j];
    }
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
