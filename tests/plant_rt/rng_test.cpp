// The plant's generator: Gaussians made a block at a time must be the polar method's sequence
// drawn pair by pair (a seed reproduces a run bit for bit, across this change too), and normal.
#include <gtest/gtest.h>

#include <cmath>

#include "hil/plant/rng.hpp"

using hil::plant::Rng;

namespace {
// Marsaglia's polar method, one pair at a time from the same uniforms: the textbook order.
struct PairByPair {
  Rng uniforms;
  double spare = 0;
  bool has_spare = false;
  double next() {
    if (has_spare) {
      has_spare = false;
      return spare;
    }
    double u = 0, v = 0, q = 0;
    do {
      u = 2 * uniforms.uniform() - 1;
      v = 2 * uniforms.uniform() - 1;
      q = u * u + v * v;
    } while (q >= 1 || q == 0);
    const double f = std::sqrt(-2 * std::log(q) / q);
    spare = v * f;
    has_spare = true;
    return u * f;
  }
};
}  // namespace

TEST(Rng, GaussiansInBlocksAreThePolarMethodsPairsInOrder) {
  for (std::uint64_t seed : {1ULL, 5ULL, 0x5eed5eedULL}) {
    Rng blocks(seed);
    PairByPair reference{Rng(seed)};
    // Several blocks, and an odd count: a block boundary falls between and inside pairs.
    for (int i = 0; i < 1001; ++i) ASSERT_EQ(blocks.gaussian(), reference.next()) << "seed " << seed << ", draw " << i;
  }
}

TEST(Rng, GaussiansHaveZeroMeanAndUnitVariance) {
  Rng rng(42);
  const int n = 200000;
  double sum = 0, sum2 = 0;
  for (int i = 0; i < n; ++i) {
    const double g = rng.gaussian();
    sum += g, sum2 += g * g;
  }
  const double mean = sum / n, var = sum2 / n - mean * mean;
  // 5 standard errors: sigma/sqrt(n) = 0.0022 for the mean, sqrt(2/n) = 0.0032 for the variance.
  EXPECT_NEAR(mean, 0.0, 0.011);
  EXPECT_NEAR(var, 1.0, 0.016);
}
