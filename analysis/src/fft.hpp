// A small iterative radix-2 FFT (internal): enough for the residual spectra and correlations of
// the workbench; sizes are powers of two.
#pragma once

#include <complex>
#include <cstddef>
#include <vector>

namespace hil::analysis::detail {

class Fft {
 public:
  explicit Fft(std::size_t n);  // n: a power of two
  std::size_t size() const { return n_; }
  void forward(std::vector<std::complex<double>>& a) const { run(a, false); }
  void inverse(std::vector<std::complex<double>>& a) const { run(a, true); }  // scaled by 1/n

 private:
  void run(std::vector<std::complex<double>>& a, bool inverse) const;
  std::size_t n_;
  std::vector<std::complex<double>> twiddle_;
};

std::size_t next_pow2(std::size_t n);

}  // namespace hil::analysis::detail
