#include "hil/analysis/noise_model.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <unordered_map>

#include "hil/units.hpp"

namespace hil::analysis {
namespace {

// Histogram of |x| on log-spaced bins, for a streaming median.
class LogHistogram {
 public:
  void add(double x) {
    x = std::abs(x);
    ++total_;
    if (x <= kLo) {
      ++zero_;
      return;
    }
    const int i = std::clamp(static_cast<int>(std::log10(x / kLo) * kPerDecade), 0, kBins - 1);
    ++bins_[static_cast<std::size_t>(i)];
  }
  double median() const {
    if (total_ == 0) return 0;
    const double half = 0.5 * static_cast<double>(total_);
    double cum = static_cast<double>(zero_);
    if (cum >= half) return 0;
    for (int i = 0; i < kBins; ++i) {
      const double c = static_cast<double>(bins_[static_cast<std::size_t>(i)]);
      if (cum + c >= half) {
        const double f = c > 0 ? (half - cum) / c : 0.5;  // log-linear inside the bin
        return kLo * std::pow(10.0, (i + f) / kPerDecade);
      }
      cum += c;
    }
    return kLo * std::pow(10.0, kBins / kPerDecade);
  }

 private:
  static constexpr double kLo = 1e-3;  // Pa
  static constexpr double kPerDecade = 100;
  static constexpr int kBins = 1000;  // 1e-3 .. 1e7 Pa
  std::array<std::size_t, kBins> bins_{};
  std::size_t zero_ = 0, total_ = 0;
};

// The robust RMS of a stream of differences of the reading (1.4826 * median|d|, Gaussian d): the
// median ignores the transients the differences still carry. A reading that
// comes off an ADC in steps of q makes every difference a multiple of q, and the plain
// median then sits on a multiple of q: 3 kPa instead of 3.3 kPa for 2 kPa noise in 1 kPa steps, a
// sigma 10 % low and a noise floor that no model can reach. So the distinct |d2| values are
// counted exactly while there are few of them; when 99 % of them are multiples of the smallest,
// the median is read as grouped data (multiple j stands for [(j - 1/2) q, (j + 1/2) q], j = 0 for
// [0, q/2]), which estimates the noise a perfect model leaves: sigma^2 + q^2/12 (quantisation
// error included). Fine lattices (a 1 Pa log resolution) overflow the exact count and need no
// correction.
class RobustRms {
 public:
  void add(double d2_pa) {
    hist_.add(d2_pa);
    sum2_ += d2_pa * d2_pa;
    ++n_;
    if (overflow_) return;
    ++exact_[std::llround(std::min(std::abs(d2_pa), 1e12) * kKeyPerPa)];
    if (exact_.size() > kMaxDistinct) overflow_ = true, exact_.clear();
  }
  // RMS of the differences (a Gaussian's: 1.4826 times the median of |d|).
  double rms_pa() const {
    if (const double q = lattice_step_pa(); q > 0) return 1.4826 * grouped_median(q);
    const double med = hist_.median();
    if (med > 0) return 1.4826 * med;
    return n_ > 0 ? std::sqrt(sum2_ / static_cast<double>(n_)) : 0.0;
  }
  std::size_t count() const { return n_; }
  double step_pa() const { return lattice_step_pa(); }  // the ADC step the differences sit on (0: none)
  // Mean square of the differences of a reading on a lattice (step_pa() > 0; NaN else), those
  // beyond kTrimSigmas robust RMS left out: a variance whatever the differences' shape, still
  // blind to the few huge ones a hole in the log or a fast transient leaves.
  double trimmed_mean_square_pa2() const {
    const double q = lattice_step_pa();
    if (!(q > 0)) return std::nan("");
    const double limit_pa = kTrimSigmas * 1.4826 * grouped_median(q);
    double sum = 0, n = 0;
    for (const auto& [key, count] : exact_) {
      const double d_pa = static_cast<double>(key) / kKeyPerPa;
      if (d_pa <= limit_pa) sum += d_pa * d_pa * static_cast<double>(count), n += static_cast<double>(count);
    }
    return n > 0 ? sum / n : std::nan("");
  }
  // How rms_pa() was read, for the noise's method text.
  std::string how() const {
    if (const double q = lattice_step_pa(); q > 0) {
      char b[160];
      std::snprintf(b, sizeof b, "the median read as grouped data of a reading quantised in %.4g kPa steps",
                    q / units::kPaPerKpa);
      return b;
    }
    if (hist_.median() > 0) return "1.4826 * median";
    return "RMS (the reading is too coarsely quantised for the median)";
  }

 private:
  static constexpr double kKeyPerPa = 1e6;  // exact to a micro-pascal
  // Trim of the mean square: a Gaussian loses 0.1 % of its variance beyond 4 sigma (1.5 % when
  // the robust RMS reads 20 % low, an undithered reading), while a chamber's transients leave
  // differences of a few sigma: at 6 sigma 2 kPa of white noise in 4 kPa steps at 200 Hz read
  // 4.8 % high, at 4 sigma 1.3 %.
  static constexpr double kTrimSigmas = 4;
  static constexpr std::size_t kMaxDistinct = 4096;
  // The step q when 99 % of the second differences are multiples of the smallest nonzero one; 0 else.
  double lattice_step_pa() const {
    if (overflow_ || exact_.empty()) return 0;
    long long q = 0;
    for (const auto& [key, count] : exact_)
      if (key > 0 && (q == 0 || key < q)) q = key;
    if (q == 0) return 0;
    std::size_t on = 0, total = 0;
    for (const auto& [key, count] : exact_) {
      const double j = static_cast<double>(key) / static_cast<double>(q);
      total += count;
      if (std::abs(j - std::round(j)) < 1e-3) on += count;
    }
    return on >= 0.99 * static_cast<double>(total) ? static_cast<double>(q) / kKeyPerPa : 0.0;
  }
  double grouped_median(double q_pa) const {
    std::vector<std::pair<long long, std::size_t>> bins;  // multiple of q, count
    std::size_t total = 0;
    for (const auto& [key, count] : exact_) {
      bins.push_back({std::llround(static_cast<double>(key) / kKeyPerPa / q_pa), count});
      total += count;
    }
    std::sort(bins.begin(), bins.end());
    const double half = 0.5 * static_cast<double>(total);
    double cum = 0;
    for (std::size_t i = 0; i < bins.size(); ++i) {
      std::size_t c = bins[i].second;
      while (i + 1 < bins.size() && bins[i + 1].first == bins[i].first) c += bins[++i].second;  // off-lattice strays
      const double j = static_cast<double>(bins[i].first);
      const double lo = j == 0 ? 0.0 : (j - 0.5) * q_pa, width = j == 0 ? 0.5 * q_pa : q_pa;
      if (cum + static_cast<double>(c) >= half) return lo + (half - cum) / static_cast<double>(c) * width;
      cum += static_cast<double>(c);
    }
    return 0;
  }
  LogHistogram hist_;
  double sum2_ = 0;
  std::size_t n_ = 0;
  std::unordered_map<long long, std::size_t> exact_;
  bool overflow_ = false;
};

// Third differences at spacing a, y(k) - 3 y(k-a) + 3 y(k-2a) - y(k-3a): they cancel a pressure
// that is locally quadratic, so the chamber's own dynamics (0.1 s) stay far below the noise even
// across a few milliseconds (a 1 MPa step leaves at most p''' (a dt)^3 = 0.5 kPa at a = 8 ms),
// while the noise's correlation over a few rows shows as their variance growing with a:
//   V(a) = 20 white^2 + coloured^2 h(a),  h(a) = 20 - 30 phi^a + 12 phi^2a - 2 phi^3a,
// from 20 white^2 + coloured^2 h(1) at a = 1 to 20 sigma^2 once the colour has decorrelated.
// Spacings reach kMaxSpacingS of time (the chamber's curvature grows with it) and at least the
// first kMinSpacings rows.
constexpr double kMaxSpacingS = 0.008;
constexpr std::size_t kMinSpacings = 4;
constexpr std::array<std::size_t, 12> kSpacings = {1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64};
constexpr std::size_t kRowsForDt = 64;  // rows buffered to read the sample period before the spacings are set
// The colour is accepted when it fits the V(a) better than white noise by this many times the
// scatter of a median-based variance (a chi-square of 2 degrees of freedom at about 0.7 %).
constexpr double kColourEvidence = 10;
constexpr double kPhiStep = 0.0025;
// A reading in ADC steps q: y = Q(x), x = p + n. The quantisation error e = Q(x) - x is a
// sawtooth of x, so its moments given the pressure p follow from the noise's characteristic
// function at the quantiser's frequencies 2 pi l/q, exp(-2 pi^2 l^2 s^2/q^2) for Gaussian noise of
// RMS s (Widrow & Kollar, Quantization Noise, 2008, ch. 4-5; Sheppard's corrections):
//   E[e^2 | p] = q^2/12 (1 + (12/pi^2) sum_l (-1)^l exp(-2 pi^2 l^2 s^2/q^2) cos(2 pi l p/q)/l^2).
// With s >= kDitherNoisePerStep q = 0.6 q that varies with where p sits between two steps by at
// most 0.1 % (at q/2 by 0.9 %, at 0.3 q by 21 %): the noise dithers the quantiser, e is noise of
// q^2/12 of its own, independent of p, and the reading is p + (n + e), the model above with e in
// its white part (a correlation e keeps between rows, when n changes little from one row to the
// next, is counted as colour: it is in a perfect model's residual too). The third differences then
// have one shape at every spacing and their robust (median) variance holds. Not dithered, e
// follows p, and the differences' distribution changes its shape (not its variance) with the
// spacing as p moves across steps between the rows they span: 300 Pa of white noise in 1 kPa
// steps on a slow sine has P(d = 0) = 0.45 at a = 1 and 0.18 at a = 32 while the mean square stays
// 20 (0.416 kPa)^2, and the median read 0.79 kPa of "colour" for 0.42. A mean square adds variances
// whatever the shape, so there V(a) is the differences' mean square
// (RobustRms::trimmed_mean_square_pa2). The test: s^2 from the mean square at the widest spacing
// (the colour decorrelated) less the q^2/12 a dithered error adds (an undithered one adds less, so
// s reads low and the test errs towards the shape-free reading). The bar at 0.1 % is ten times
// below what the colour test resolves from 30 000 rows (kColourEvidence): at s = q/2 the median
// still read 0.38 kPa of colour into 0.5 kPa of white noise, 1 draw in 3. The median where it
// holds, because a chamber's fast transients and a log's holes leave differences of a few sigma
// that a mean square counts (1 kPa of coloured noise on a chamber stepping every 2.5 s: sigma +3
// to +10 % from the mean squares, 0 to +5 % from the median). Steps coarser than half the noise
// must not make the reading white, from second differences, which see only the part of a colour
// that changes between rows (6 - 8 phi + 2 phi^2 of 6 coloured^2): 1 kPa behind a 50 Hz filter
// plus 0.3 kPa white, in 1 kPa steps (s = 1.04 q: dithered), would read 0.64 kPa for 1.08, and
// healthy DAQ logs would be `unexplained`.
constexpr double kDitherNoisePerStep = 0.6;

double h_of(double phi, std::size_t a) {
  const double p = std::pow(phi, static_cast<double>(a));
  return 20 - 30 * p + 12 * p * p - 2 * p * p * p;
}

// Least squares of V(a) (relative errors) by 20 W + h(a) A with W, A >= 0, for one phi.
// Returns the relative SSE; W and A out.
double fit_levels(const std::vector<std::size_t>& spacings, const std::vector<double>& v, double phi, double& w, double& a) {
  double s11 = 0, s12 = 0, s22 = 0, b1 = 0, b2 = 0;
  for (std::size_t i = 0; i < spacings.size(); ++i) {
    const double x1 = 20 / v[i], x2 = h_of(phi, spacings[i]) / v[i];
    s11 += x1 * x1, s12 += x1 * x2, s22 += x2 * x2, b1 += x1, b2 += x2;
  }
  const double det = s11 * s22 - s12 * s12;
  w = det > 0 ? (b1 * s22 - b2 * s12) / det : 0;
  a = det > 0 ? (b2 * s11 - b1 * s12) / det : 0;
  if (!(det > 0) || a < 0) a = 0, w = b1 / s11;
  if (w < 0) w = 0, a = s22 > 0 ? b2 / s22 : 0;
  double sse = 0;
  for (std::size_t i = 0; i < spacings.size(); ++i) {
    const double r = 1 - (20 * w + h_of(phi, spacings[i]) * a) / v[i];
    sse += r * r;
  }
  return sse;
}

}  // namespace

double NoiseModel::corner_hz() const {
  if (!coloured() || !(sample_period_s > 0)) return 0;
  return -std::log(phi) / (2 * std::numbers::pi * sample_period_s);
}

double NoiseModel::correlation_time_samples() const {
  const double total = coloured_sigma_pa * coloured_sigma_pa + white_sigma_pa * white_sigma_pa;
  if (!coloured() || !(total > 0)) return 1;
  return 1 + 2 * coloured_sigma_pa * coloured_sigma_pa * phi / ((1 - phi) * total);
}

void NoiseModel::whiten(std::span<const double> e, std::span<double> out) const {
  const double inv = innovation_sigma_pa > 0 ? 1 / innovation_sigma_pa : 1;  // noise-free data: plain sums
  if (e.empty()) return;
  out[0] = 0;
  double eps = 0;
  for (std::size_t k = 1; k < e.size(); ++k) {
    eps = e[k] - phi * e[k - 1] + theta * eps;
    out[k] = eps * inv;
  }
}

double NoiseModel::whitened_rss(std::span<const double> e) const {
  const double inv = innovation_sigma_pa > 0 ? 1 / innovation_sigma_pa : 1;  // noise-free data: plain sums
  double eps = 0, sum = 0;
  for (std::size_t k = 1; k < e.size(); ++k) {
    eps = e[k] - phi * e[k - 1] + theta * eps;
    sum += eps * eps;
  }
  return sum * inv * inv;
}

struct NoiseEstimator::Impl {
  std::vector<double> t_buffer, y_buffer;  // the first rows, until the sample period is known
  bool started = false;
  double dt_s = 0;
  std::vector<std::size_t> spacings;
  std::vector<RobustRms> rms;  // per spacing
  std::vector<double> ring;    // the last 3 a_max + 1 readings
  std::size_t head = 0, seen = 0;

  void start(double dt) {
    started = true;
    dt_s = dt;
    for (std::size_t a : kSpacings)
      if (spacings.size() < kMinSpacings || (dt > 0 && static_cast<double>(a) * dt <= kMaxSpacingS * (1 + 1e-9)))
        spacings.push_back(a);
    rms.resize(spacings.size());
    ring.assign(3 * spacings.back() + 1, 0.0);
  }
  void push(double y) {
    const std::size_t n = ring.size();
    ring[head] = y;
    ++seen;
    auto at = [&](std::size_t back) { return ring[(head + n - back) % n]; };  // back rows ago
    for (std::size_t i = 0; i < spacings.size(); ++i) {
      const std::size_t a = spacings[i];
      if (seen <= 3 * a) break;
      rms[i].add(y - 3 * at(a) + 3 * at(2 * a) - at(3 * a));
    }
    head = (head + 1) % n;
  }
  void add(double t, double y) {
    if (started) return push(y);
    t_buffer.push_back(t);
    y_buffer.push_back(y);
    if (t_buffer.size() >= kRowsForDt) flush();
  }
  void flush() {
    std::vector<double> dts;
    for (std::size_t k = 1; k < t_buffer.size(); ++k) dts.push_back(t_buffer[k] - t_buffer[k - 1]);
    double dt = 0;
    if (!dts.empty()) {
      std::nth_element(dts.begin(), dts.begin() + static_cast<std::ptrdiff_t>(dts.size() / 2), dts.end());
      dt = dts[dts.size() / 2];
    }
    start(dt > 0 && std::isfinite(dt) ? dt : 1e-3);
    for (double y : y_buffer) push(y);
    t_buffer.clear(), y_buffer.clear();
  }
};

NoiseEstimator::NoiseEstimator() : impl_(std::make_unique<Impl>()) {}
NoiseEstimator::~NoiseEstimator() = default;
NoiseEstimator::NoiseEstimator(NoiseEstimator&&) noexcept = default;
NoiseEstimator& NoiseEstimator::operator=(NoiseEstimator&&) noexcept = default;

void NoiseEstimator::add(double t_s, double y_pa) { impl_->add(t_s, y_pa); }

NoiseModel NoiseEstimator::finish() {
  Impl& im = *impl_;
  if (!im.started) im.flush();  // a short stream: its rows are still buffered
  NoiseModel m;
  m.sample_period_s = im.dt_s;
  std::vector<std::size_t> sp;
  std::vector<double> v;
  std::vector<const RobustRms*> used;
  std::size_t n_first = 0;
  for (std::size_t i = 0; i < im.spacings.size(); ++i) {
    if (im.rms[i].count() < 16) continue;
    const double r = im.rms[i].rms_pa();
    if (!(r > 0)) continue;
    if (sp.empty()) n_first = im.rms[i].count();
    sp.push_back(im.spacings[i]);
    v.push_back(r * r);
    used.push_back(&im.rms[i]);
  }
  if (sp.empty()) {
    m.method = "too few rows for a noise estimate";
    return m;
  }
  // A reading in ADC steps its noise does not dither: V(a) from the mean squares (above).
  std::string how = im.rms.front().how();
  if (const double q = im.rms.front().step_pa(); q > 0) {
    const double s2 = used.back()->trimmed_mean_square_pa2() / 20 - q * q / 12;
    if (!(s2 >= kDitherNoisePerStep * kDitherNoisePerStep * q * q)) {
      // Only the spacings inside kMaxSpacingS: beyond, the chamber's curvature is in the rows
      // around each transient, which a median passes over and a mean square counts.
      std::vector<double> ms;
      for (std::size_t i = 0; i < used.size(); ++i) {
        if (i > 0 && static_cast<double>(sp[i]) * im.dt_s > kMaxSpacingS * (1 + 1e-9)) break;
        ms.push_back(used[i]->trimmed_mean_square_pa2());
      }
      if (std::all_of(ms.begin(), ms.end(), [](double x) { return x > 0; })) {
        v = ms;
        sp.resize(ms.size());
        char b[200];
        std::snprintf(b, sizeof b,
                      "mean squares of a reading in %.4g kPa steps that its noise (%.3g kPa) does not dither: the "
                      "quantisation error follows the pressure",
                      q / units::kPaPerKpa, std::sqrt(std::max(s2, 0.0)) / units::kPaPerKpa);
        how = b;
      }
    }
  }
  double w0 = 0, a0 = 0;
  const double sse_white = fit_levels(sp, v, 0.0, w0, a0);  // phi = 0: h = 20, all white
  double best_sse = sse_white, w = w0 + a0, a = 0, phi = 0;
  if (sp.size() >= 3) {
    for (double p = kPhiStep; p <= kNoiseMaxPhi + 1e-12; p += kPhiStep) {
      double wi = 0, ai = 0;
      const double sse = fit_levels(sp, v, p, wi, ai);
      if (ai > 0 && sse < best_sse) best_sse = sse, w = wi, a = ai, phi = p;
    }
  }
  // The scatter of one relative variance from a median of N (correlated) differences.
  const double s2 = 2.33 * 2.33 * 3.0 / static_cast<double>(std::max<std::size_t>(n_first, 1));
  if (!(sse_white - best_sse > kColourEvidence * s2)) w = w0 + a0, a = 0, phi = 0;
  m.white_sigma_pa = std::sqrt(w);
  m.coloured_sigma_pa = std::sqrt(a);
  m.phi = a > 0 ? phi : 0;
  m.sigma_pa = std::sqrt(w + a);
  // Innovations form: (1 - phi q^-1) n is MA(1) with autocovariances g0, g1 = -phi W.
  const double g0 = a * (1 - phi * phi) + w * (1 + phi * phi);
  const double r = g0 > 0 ? phi * w / g0 : 0;
  m.theta = r > 1e-12 ? (1 - std::sqrt(std::max(0.0, 1 - 4 * r * r))) / (2 * r) : 0;
  m.innovation_sigma_pa = std::sqrt(g0 / (1 + m.theta * m.theta));
  char b[400];
  if (m.coloured()) {
    std::snprintf(
        b, sizeof b,
        "noise process from third differences of p_meas at spacings 1-%zu rows (%s): first-order coloured "
        "%.3g kPa (phi %.3f per row%s) plus white %.3g kPa",
        sp.back(), how.c_str(), m.coloured_sigma_pa / units::kPaPerKpa, m.phi,
        m.corner_hz() > 0 ? (", corner " + std::to_string(static_cast<int>(std::lround(m.corner_hz()))) + " Hz").c_str() : "",
        m.white_sigma_pa / units::kPaPerKpa);
  } else {
    std::snprintf(b, sizeof b,
                  "noise process from third differences of p_meas at spacings 1-%zu rows (%s): white (no colour "
                  "the differences can tell)",
                  sp.back(), how.c_str());
  }
  m.method = b;
  return m;
}

NoiseModel noise_model_from_data(std::span<const double> y_pa, double sample_period_s) {
  NoiseEstimator e;
  const double dt = sample_period_s > 0 ? sample_period_s : 1e-3;
  for (std::size_t k = 0; k < y_pa.size(); ++k) e.add(static_cast<double>(k) * dt, y_pa[k]);
  return e.finish();
}

double noise_sigma_from_data(const std::vector<double>& y_pa) { return noise_model_from_data(y_pa).sigma_pa; }

}  // namespace hil::analysis
