// The gap fit on a synthetic history with a known gap.
#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <cstdint>
#include <cmath>
#include <memory>
#include <random>

#include "hil/ctl/gap_fit.hpp"

using hil::ctl::GapFit;

namespace {

constexpr double kDeg = M_PI / 180;

// The motor rests on the old flank (pushing in -dir), turns at `turn`, crosses at `speed`.
GapFit::History history(double gap, int dir, double speed_deg_s, double noise_deg, int turn, int n, std::int64_t* extreme,
                        double* extreme_rad) {
  const double alpha = 1 - std::exp(-1e-3 / 0.015);
  GapFit::History h;
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0, noise_deg * kDeg);
  double motor = 0.2, valve = motor + dir * gap / 2, lp1 = valve, lp2 = valve;
  for (int k = 0; k < n; ++k) {
    if (k > turn) motor += dir * speed_deg_s * kDeg * 1e-3;
    if (motor - gap / 2 > valve) valve = motor - gap / 2;
    if (motor + gap / 2 < valve) valve = motor + gap / 2;
    lp1 += alpha * (valve - lp1);
    lp2 += alpha * (lp1 - lp2);
    GapFit::push(h, motor, lp2 + noise(rng));
  }
  *extreme = turn;
  *extreme_rad = 0.2;
  return h;
}

TEST(GapFit, RecoversTheGapThroughTheFilters) {
  const GapFit fit(1 - std::exp(-1e-3 / 0.015), 6 * kDeg);
  for (double gap_deg : {0.6, 1.3, 2.4}) {
    for (int dir : {-1, +1}) {
      std::int64_t ext;
      double ext_rad;
      // Slow enough that the valve moves well after contact within the window.
      auto h = history(gap_deg * kDeg, dir, 8.0, 0.02, 50, 50 + static_cast<int>(gap_deg / 8.0 * 1000) + 120, &ext, &ext_rad);
      const auto r = fit.fit(h, ext, ext_rad, dir, 20, 30);
      ASSERT_TRUE(r.ok) << gap_deg << " dir " << dir;
      EXPECT_NEAR(r.gap_rad / kDeg, gap_deg, 0.03) << "dir " << dir;
      EXPECT_LT(r.rms_rad / kDeg, 0.03);
    }
  }
}

TEST(GapFit, NoContactNoMeasurement) {
  const GapFit fit(1 - std::exp(-1e-3 / 0.015), 6 * kDeg);
  std::int64_t ext;
  double ext_rad;
  // The motor crosses only half of a 2 deg gap: the valve never moves.
  auto h = history(2.0 * kDeg, +1, 8.0, 0.02, 50, 50 + 125, &ext, &ext_rad);
  EXPECT_FALSE(fit.fit(h, ext, ext_rad, +1, 20, 30).ok);
}

// A reversal within the first `lead` samples of a run (a reference reversing at 0.05 s at 1 kHz):
// the window must start at the first sample, not `lead` samples before the extreme. The history
// sits right behind a block of far-away angles, so a fit that reads before the ring's first
// element (negative slots) sees them and misses the gap; AddressSanitizer/UBSan report the read.
TEST(GapFit, ReversalBeforeTheLeadFitsFromTheFirstSample) {
  const GapFit fit(1 - std::exp(-1e-3 / 0.015), 6 * kDeg);
  for (int dir : {-1, +1}) {
    struct Guarded {
      std::array<double, 256> before;
      GapFit::History h;
    };
    auto g = std::make_unique<Guarded>();
    g->before.fill(1e3);
    std::int64_t ext;
    double ext_rad;
    const double gap_deg = 1.3;
    g->h = history(gap_deg * kDeg, dir, 8.0, 0.02, 30, 30 + static_cast<int>(gap_deg / 8.0 * 1000) + 120, &ext, &ext_rad);
    ASSERT_LT(ext, 50);
    const auto r = fit.fit(g->h, ext, ext_rad, dir, 50, 30);
    ASSERT_TRUE(r.ok) << "dir " << dir;
    EXPECT_NEAR(r.gap_rad / kDeg, gap_deg, 0.03) << "dir " << dir;
    EXPECT_LT(r.rms_rad / kDeg, 0.03) << "dir " << dir;
  }
}

// A reversal at the very first sample, and a fit asked before enough samples exist.
TEST(GapFit, ReversalAtTheFirstSampleAndTooFewSamples) {
  const GapFit fit(1 - std::exp(-1e-3 / 0.015), 6 * kDeg);
  std::int64_t ext;
  double ext_rad;
  auto h = history(1.3 * kDeg, +1, 8.0, 0.02, 0, 300, &ext, &ext_rad);
  const auto r = fit.fit(h, ext, ext_rad, +1, 50, 30);
  ASSERT_TRUE(r.ok);
  EXPECT_NEAR(r.gap_rad / kDeg, 1.3, 0.05);
  auto few = history(1.3 * kDeg, +1, 8.0, 0.02, 0, 20, &ext, &ext_rad);
  EXPECT_FALSE(fit.fit(few, ext, ext_rad, +1, 50, 30).ok);
}

}  // namespace

// The cost lanes come four to an AVX2 register or two to an SSE2 one (GapFit::use_wide_lanes):
// the fits must be the same bits, over gaps, directions, noise and a window that starts before
// the extreme as well as after it.
TEST(GapFit, WideAndNarrowLanesGiveTheSameBits) {
  if (!GapFit::use_wide_lanes(true)) GTEST_SKIP() << "this CPU has no AVX2: only the SSE2 lanes exist";
  const GapFit fit(1 - std::exp(-1e-3 / 0.015), 6 * kDeg);
  int compared = 0;
  for (double gap_deg : {0.3, 1.3, 2.4, 5.0}) {
    for (int dir : {-1, +1}) {
      for (double noise_deg : {0.0, 0.02, 0.3}) {
        for (std::int64_t lead : {20, 400}) {
          std::int64_t ext;
          double ext_rad;
          auto h = history(gap_deg * kDeg, dir, 8.0, noise_deg, 300, 1000, &ext, &ext_rad);
          GapFit::use_wide_lanes(true);
          const auto wide = fit.fit(h, ext, ext_rad, dir, lead, 30);
          GapFit::use_wide_lanes(false);
          const auto narrow = fit.fit(h, ext, ext_rad, dir, lead, 30);
          EXPECT_EQ(wide.ok, narrow.ok);
          EXPECT_EQ(std::bit_cast<std::uint64_t>(wide.gap_rad), std::bit_cast<std::uint64_t>(narrow.gap_rad)) << gap_deg;
          EXPECT_EQ(std::bit_cast<std::uint64_t>(wide.rms_rad), std::bit_cast<std::uint64_t>(narrow.rms_rad)) << gap_deg;
          EXPECT_EQ(std::bit_cast<std::uint64_t>(wide.excursion_rad), std::bit_cast<std::uint64_t>(narrow.excursion_rad));
          compared += wide.ok ? 1 : 0;
        }
      }
    }
  }
  GapFit::use_wide_lanes(true);
  EXPECT_GT(compared, 20);  // most of them are real measurements, not refusals
}
