#include "fft.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace hil::analysis::detail {

std::size_t next_pow2(std::size_t n) {
  std::size_t p = 1;
  while (p < n) p <<= 1;
  return p;
}

Fft::Fft(std::size_t n) : n_(n) {
  if (n < 2 || (n & (n - 1)) != 0) throw std::invalid_argument("Fft: size must be a power of two >= 2");
  twiddle_.resize(n / 2);
  for (std::size_t k = 0; k < n / 2; ++k) {
    const double a = -2 * std::numbers::pi * static_cast<double>(k) / static_cast<double>(n);
    twiddle_[k] = {std::cos(a), std::sin(a)};
  }
}

void Fft::run(std::vector<std::complex<double>>& a, bool inverse) const {
  if (a.size() != n_) throw std::invalid_argument("Fft: wrong input size");
  // The bit-reversal permutation, j = reverse(i) counted along with i (a table of n indices
  // would cost as much memory as half the data).
  for (std::size_t i = 1, j = 0; i < n_; ++i) {
    std::size_t bit = n_ >> 1;
    for (; (j & bit) != 0; bit >>= 1) j ^= bit;
    j ^= bit;
    if (i < j) std::swap(a[i], a[j]);
  }
  for (std::size_t len = 2; len <= n_; len <<= 1) {
    const std::size_t half = len / 2, step = n_ / len;
    for (std::size_t i = 0; i < n_; i += len) {
      for (std::size_t j = 0; j < half; ++j) {
        std::complex<double> w = twiddle_[j * step];
        if (inverse) w = std::conj(w);
        const std::complex<double> u = a[i + j], v = a[i + j + half] * w;
        a[i + j] = u + v;
        a[i + j + half] = u - v;
      }
    }
  }
  if (inverse) {
    const double s = 1.0 / static_cast<double>(n_);
    for (auto& x : a) x *= s;
  }
}

}  // namespace hil::analysis::detail
