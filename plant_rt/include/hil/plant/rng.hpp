// A small deterministic random generator (xoshiro256**, seeded by splitmix64) with Gaussian
// samples by the polar method. Chosen over <random> because its output is the same on every
// standard library, so a seed reproduces a run bit for bit. Real-time safe.
#pragma once

#include <cmath>
#include <cstdint>

namespace hil::plant {

class Rng {
 public:
  explicit Rng(std::uint64_t seed = 1) noexcept {
    for (auto& w : s_) {
      seed += 0x9e3779b97f4a7c15ULL;
      std::uint64_t z = seed;
      z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
      z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
      w = z ^ (z >> 31);
    }
  }
  std::uint64_t next() noexcept {
    const std::uint64_t result = rotl(s_[1] * 5, 7) * 9;
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }
  // Uniform in [0, 1).
  double uniform() noexcept { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  // Standard normal: the polar method's pairs in order (u f, then v f), made kGaussianBlock at a
  // time. The block is the same sequence one pair at a time would give, and faster in a
  // simulation's period: its logs and square roots run side by side in one loop instead of one
  // behind the plant's chain of dependent steps every other period. The price: a Gaussian draw
  // takes the uniforms of a whole block ahead, so a generator must draw only uniforms or only
  // Gaussians (every one here does; mixing them would change the numbers, not their quality).
  double gaussian() noexcept {
    if (next_gaussian_ == kGaussianBlock) [[unlikely]] {
      for (int i = 0; i < kGaussianBlock; i += 2) {
        double u = 0, v = 0, q = 0;
        do {
          u = 2 * uniform() - 1;
          v = 2 * uniform() - 1;
          q = u * u + v * v;
        } while (q >= 1 || q == 0);
        const double f = std::sqrt(-2 * std::log(q) / q);
        gaussians_[i] = u * f;
        gaussians_[i + 1] = v * f;
      }
      next_gaussian_ = 0;
    }
    return gaussians_[next_gaussian_++];
  }

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) noexcept { return (x << k) | (x >> (64 - k)); }
  std::uint64_t s_[4]{};
  static constexpr int kGaussianBlock = 32;  // even: whole pairs
  double gaussians_[kGaussianBlock]{};
  int next_gaussian_ = kGaussianBlock;
};

}  // namespace hil::plant
