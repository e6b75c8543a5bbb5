// The tracking compensator's two estimators against closed forms: the noise estimator recovers
// the RMS of white Gaussian noise on a chamber-like pressure (E|d2| = sqrt(12/pi) s), ignores a
// pressure step, and reads nothing on a noise-free signal; the gap tracker predicts a gap growing
// at a constant rate exactly from its second measurement on, learns a stop in two, and believes
// no rate beyond its limit; the in-gap step filter keeps of white steps the variance of one
// first-order stage, alpha / (2 - alpha), passes a constant walk at its own speed, and loses no
// step (at a flank all it held passes).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "hil/ctl/tracking.hpp"

using namespace hil::ctl;

namespace {

constexpr double kDt = 1e-3;

// A first-order chamber (tau 0.1 s) behind a first-order drive (20 ms) whose target steps by
// 0.3 MPa every 1.5 s and wanders slowly: the kind of signal the transducer sees.
struct Chamber {
  double drive_pa = 1e6, p_pa = 1e6;
  double at(int k) {
    const double target = 1e6 + ((k / 1500) % 2 == 0 ? 0.0 : 3e5) + 2e4 * std::sin(2 * M_PI * 0.7 * k * kDt);
    drive_pa += (target - drive_pa) * (1 - std::exp(-kDt / 0.02));
    p_pa += (drive_pa - p_pa) * (1 - std::exp(-kDt / 0.1));
    return p_pa;
  }
};

double noise_after(double sigma_pa, int steps, double floor_pa = 0) {
  const NoiseEstimator est{1 - std::exp(-kDt / 1.0), floor_pa, 6};  // a 1 s window
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0, sigma_pa);
  Chamber chamber;
  auto s = est.initial(1e6, 2000);  // starts believing 2 kPa
  double mean = 0;
  int n = 0;
  for (int k = 0; k < steps; ++k) {
    const double e = est.update(s, chamber.at(k) + noise(rng));
    if (k >= steps - 2000) mean += e, ++n;  // the last 2 s
  }
  return mean / n;
}

TEST(TrackingNoiseEstimator, RecoversTheRmsOfWhiteNoiseOnAChamberSignal) {
  for (double sigma : {1000.0, 5000.0, 10000.0}) {
    SCOPED_TRACE(sigma);
    EXPECT_NEAR(noise_after(sigma, 8000), sigma, 0.05 * sigma);
  }
}

TEST(TrackingNoiseEstimator, ANoiseFreeSignalReadsAsNoNoiseDownToTheFloor) {
  // The chamber's own second difference over 1 ms: tens of Pa at the steps, far below any transducer.
  EXPECT_LT(noise_after(0, 8000), 100);
  EXPECT_EQ(noise_after(0, 8000, 1500), 1500);
}

TEST(TrackingNoiseEstimator, APressureStepDoesNotInflateIt) {
  const double alpha = 1 - std::exp(-kDt / 0.2);  // the default 200 ms window
  const NoiseEstimator est{alpha, 0, 6};
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0, 2000);
  auto s = est.initial(1e6, 2000);
  for (int k = 0; k < 3000; ++k) est.update(s, 1e6 + noise(rng));
  const double before = est.estimate_pa(s);
  EXPECT_NEAR(before, 2000, 200);
  for (int k = 0; k < 6; ++k) est.update(s, 1.2e6 + noise(rng));  // a 200 kPa step
  // The step is in d2 twice (+200 kPa, then -200 kPa): unclipped, the estimate would rise by
  // 2 alpha 200 kPa / sqrt(12/pi) (~1 kPa, half the noise); clipped at 6 sigmas, by at most
  // 2 alpha 6 s (~0.12 kPa), plus the four ordinary samples' wander.
  const double unclipped_rise_pa = 2 * alpha * 2e5 / NoiseEstimator::kAbsD2PerSigma;
  EXPECT_LT(est.estimate_pa(s) - before, 2 * alpha * 6 * before + 50);
  EXPECT_LT(est.estimate_pa(s) - before, unclipped_rise_pa / 5);
}

constexpr double kDeg = M_PI / 180;

TEST(TrackingGapTracker, AConstantGrowthIsPredictedExactlyFromTheSecondMeasurement) {
  const GapTracker tr{1, 1, 1 * kDeg, 6 * kDeg};
  GapTracker::State s;
  const double rate = 0.5 * kDeg;  // deg/s, the corner's worst
  auto gap = [&](double t) { return 1 * kDeg + rate * t; };
  EXPECT_EQ(tr.estimate_rad(s, 0.3, 0.7), 0.7);          // nothing measured: the fallback
  const double times[] = {1.04, 2.61, 3.9, 5.55, 7.02};  // irregular, as reversals are
  for (int i = 0; i < 5; ++i) {
    tr.measure(s, gap(times[i]), times[i]);
    if (i == 0) {
      EXPECT_EQ(tr.estimate_rad(s, 2.0, 0), gap(times[0]));  // a level, no rate yet
      continue;
    }
    for (double later : {0.0, 0.4, 1.5}) EXPECT_NEAR(tr.estimate_rad(s, times[i] + later, 0), gap(times[i] + later), 1e-12);
  }
}

// A fit measures the motor's travel from its last push on the old flank (at p) to the contact
// with the new one (at c): with the play symmetric about the motor, half the gap at p plus half at
// c. Taken as of the midpoint, a constant growth is predicted exactly from the second measurement
// on; taken as of the contact, as if it were the gap then, it stays r (c - p) / 2 behind.
TEST(TrackingGapTracker, ATravelMeasuresTheGapAtTheMidpointOfItsPushAndContact) {
  const GapTracker tr{1, 1, 1 * kDeg, 6 * kDeg};
  const double rate = 0.5 * kDeg;  // deg/s
  auto gap = [&](double t) { return 1 * kDeg + rate * t; };
  const double push[] = {0.3, 1.7, 3.1, 4.4}, contact[] = {1.05, 2.56, 3.2, 5.58};  // pushes as old as 1.2 s
  GapTracker::State mid, at_contact;
  for (int i = 0; i < 4; ++i) {
    const double travel = gap(push[i]) / 2 + gap(contact[i]) / 2;
    tr.measure_travel(mid, travel, push[i], contact[i]);
    tr.measure(at_contact, travel, contact[i]);
    if (i == 0) continue;
    for (double later : {0.0, 1.5}) EXPECT_NEAR(tr.estimate_rad(mid, contact[i] + later, 0), gap(contact[i] + later), 1e-12);
  }
  EXPECT_NEAR(tr.estimate_rad(at_contact, contact[3], 0), gap(contact[3]) - rate * (contact[3] - push[3]) / 2, 1e-12);
  // A push older than the last measurement's midpoint does not put the measurement before it.
  GapTracker::State s;
  tr.measure(s, 1 * kDeg, 2.0);
  tr.measure_travel(s, 1.5 * kDeg, 0.5, 3.0);  // midpoint 1.75 < 2.0: taken as of 2.0
  EXPECT_EQ(s.at_s, 2.0);
  EXPECT_NEAR(tr.estimate_rad(s, 2.0, 0), 1.5 * kDeg, 1e-12);
}

TEST(TrackingGapTracker, AGrowthThatStopsIsLearntInTwoMeasurements) {
  const GapTracker tr{1, 1, 1 * kDeg, 6 * kDeg};
  GapTracker::State s;
  auto gap = [&](double t) { return (1 + 0.5 * std::clamp(t - 5, 0.0, 4.0)) * kDeg; };  // the sweep's drift
  for (double t : {5.5, 7.0, 8.5}) tr.measure(s, gap(t), t);
  // Between 8.5 and 10 the rate still says 0.5 deg/s: 0.5 deg too much at 10 s (the drift ended at 9).
  EXPECT_NEAR(tr.estimate_rad(s, 10, 0), gap(10) + 0.5 * kDeg, 1e-12);
  tr.measure(s, gap(10), 10);
  tr.measure(s, gap(11.5), 11.5);  // both after the stop: the rate is 0 again
  EXPECT_NEAR(tr.estimate_rad(s, 13, 0), gap(13), 1e-12);
}

TEST(TrackingGapTracker, NoRateBeyondItsLimitAndNoGapOutsideItsRange) {
  const GapTracker tr{1, 1, 1 * kDeg, 6 * kDeg};
  GapTracker::State s;
  tr.measure(s, 1 * kDeg, 0);
  tr.measure(s, 5 * kDeg, 1);  // 4 deg/s: believed as 1 deg/s
  EXPECT_NEAR(tr.estimate_rad(s, 2, 0), 6 * kDeg, 1e-12);
  EXPECT_NEAR(tr.estimate_rad(s, 1.5, 0), 5.5 * kDeg, 1e-12);
  EXPECT_EQ(tr.estimate_rad(s, 9, 0), 6 * kDeg);  // the largest gap
  tr.measure(s, 0.2 * kDeg, 2);                   // shrinking fast: clamped at 0, not negative
  EXPECT_EQ(tr.estimate_rad(s, 30, 0), 0);
}

TEST(TrackingGapStepFilter, InTheGapWhiteStepsKeepOneStagesVarianceAndAWalkItsSpeed) {
  const double alpha = 1 - std::exp(-kDt / 0.03);  // 30 ms, the default
  const GapStepFilter f{alpha};
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0, 1e-5);
  double held = 0, sum = 0, sum2 = 0;
  const int n = 400000;
  for (int k = 0; k < n; ++k) {
    const double passed = f.pass_rad(held, noise(rng), true);
    sum += passed;
    sum2 += passed * passed;
  }
  // One first-order stage keeps alpha / (2 - alpha) of white noise's variance (0.033 at 30 ms).
  EXPECT_NEAR(sum2 / n / (1e-5 * 1e-5), alpha / (2 - alpha), 0.03 * alpha / (2 - alpha));
  // A constant walk (the integral's response to a steady error) passes at its own speed: in the
  // steady state what is held is c (1 - alpha) / alpha, and every period passes c.
  held = 0;
  const double c = 2e-6;
  double passed = 0;
  for (int k = 0; k < 2000; ++k) passed = f.pass_rad(held, c, true);
  EXPECT_NEAR(passed, c, 1e-12);
  EXPECT_NEAR(held, c * (1 - alpha) / alpha, 1e-12);
}

TEST(TrackingGapStepFilter, NoStepIsLostAndAtAFlankAllThatIsHeldPasses) {
  const GapStepFilter f{1 - std::exp(-kDt / 0.03)};
  double held = 0, passed = 0, steps = 0;
  for (int k = 0; k < 50; ++k) {
    const double step = 1e-5 * std::sin(0.3 * k) + 3e-6;
    steps += step;
    passed += f.pass_rad(held, step, true);
    EXPECT_NEAR(passed + held, steps, 1e-15);
  }
  EXPECT_GT(std::abs(held), 0);
  // At a flank this period's step and all that was held reach the command now.
  passed += f.pass_rad(held, 1e-6, false);
  EXPECT_EQ(held, 0);
  EXPECT_NEAR(passed, steps + 1e-6, 1e-15);
  // With no filter (0 ms) every step passes unchanged.
  const GapStepFilter none{1};
  EXPECT_EQ(none.pass_rad(held, 4e-6, true), 4e-6);
  EXPECT_EQ(held, 0);
}

}  // namespace
