#include "log_checks.hpp"

#include <algorithm>
#include <cmath>

#include "hil/units.hpp"
#include "text.hpp"

namespace hil::analysis {
namespace {
constexpr std::size_t kTypicalIntervals = 1001;  // enough for a median that holes do not move
constexpr std::size_t kMaxGapsKept = 1000;
constexpr std::size_t kRunBins = 256;
}  // namespace

void LogChecks::add(double t_s, double p_pa) {
  if (rows_ == 0) {
    p_max_pa_ = p_min_pa_ = p_pa;
    at_max_ = at_min_ = 1;
    run_lengths_.assign(kRunBins + 1, 0);
  } else {
    const double dt = t_s - t_prev_s_;
    if (first_dt_s_.size() < kTypicalIntervals) first_dt_s_.push_back(dt);
    if (dt > kHoleMinS && long_gaps_.size() < kMaxGapsKept) long_gaps_.emplace_back(t_prev_s_, dt);
    if (p_pa == p_prev_pa_) {
      ++repeats_;
      ++run_;
    } else {
      ++run_lengths_[std::min(run_, kRunBins)];
      run_ = 1;
    }
    if (p_pa > p_max_pa_) p_max_pa_ = p_pa, at_max_ = 0;
    if (p_pa == p_max_pa_) ++at_max_;
    if (p_pa < p_min_pa_) p_min_pa_ = p_pa, at_min_ = 0;
    if (p_pa == p_min_pa_) ++at_min_;
  }
  t_prev_s_ = t_s;
  p_prev_pa_ = p_pa;
  sum_p_pa_ += p_pa;
  ++rows_;
}

void LogChecks::start(double p0_pa, double yhat0_pa, double angle0_rad) {
  p0_pa_ = p0_pa, yhat0_pa_ = yhat0_pa, angle0_rad_ = angle0_rad;
  started_ = true;
}

double LogChecks::typical_dt_s() const {
  if (first_dt_s_.empty()) return 0;
  std::vector<double> d = first_dt_s_;
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

std::vector<std::string> LogChecks::warnings(double noise_sigma_pa) const {
  std::vector<std::string> out;
  if (rows_ < 2) return out;
  const double dt = typical_dt_s();
  const double mpa = units::kPaPerMpa;

  // Holes: the replay crosses them open loop, guessing the inputs; what follows is the hole's.
  const double hole_s = std::max(kHoleMinS, kHoleSamples * dt);
  std::vector<std::pair<double, double>> holes;
  for (const auto& g : long_gaps_)
    if (g.second > hole_s) holes.push_back(g);
  if (!holes.empty()) {
    double total = 0;
    std::string where;
    for (std::size_t i = 0; i < holes.size(); ++i) {
      total += holes[i].second;
      if (i < 3) where += (i ? ", " : "") + text::num(holes[i].second, 3) + " s at " + text::instant(holes[i].first) + " s";
    }
    out.push_back("Log: " + std::to_string(holes.size()) + (holes.size() == 1 ? " hole" : " holes") + " in the log (" + where +
                  (holes.size() > 3 ? ", ..." : "") + "; rows normally " + text::num(1e3 * dt, 3) + " ms apart, " +
                  text::num(total, 3) +
                  " s missing in all): the replay crosses a hole open loop, guessing the command and angle, so an error "
                  "that starts there is the hole's, not the model's.");
  }

  // Stale readings: runs of equal values of about one length (a sensor or bus slower than the log).
  std::size_t runs = 0;
  for (const std::size_t n : run_lengths_) runs += n;
  if (runs > 0 && static_cast<double>(repeats_) > kStaleRepeatShare * static_cast<double>(rows_ - 1)) {
    std::size_t seen = 0, median = 1;
    for (std::size_t len = 1; len < run_lengths_.size(); ++len) {
      seen += run_lengths_[len];
      if (2 * seen >= runs) {
        median = len;
        break;
      }
    }
    // A reading updated at its own rate repeats in runs of one length (give or take a fifth, for a
    // jittery clock); a coarsely quantised one in runs of every length (a 10 kPa step at 2 kPa
    // noise: 79 % repeats, runs of 1, 2, 3, ...), which is not this.
    std::size_t near = 0;
    for (std::size_t len = median - median / 5; len <= std::min(median + median / 5, kRunBins); ++len) near += run_lengths_[len];
    if (median >= 2 && static_cast<double>(near) >= kStaleRegularShare * static_cast<double>(runs)) {
      out.push_back("Log: " + text::num(100.0 * static_cast<double>(repeats_) / static_cast<double>(rows_ - 1), 3) +
                    " % of rows repeat the pressure of the row before, in runs of about " + std::to_string(median) +
                    " rows: the reading is updated only every ~" + text::num(1e3 * dt * static_cast<double>(median), 3) +
                    " ms (a slower transducer, bus or logger task than the log's rate). The noise estimate, and any lag, "
                    "delay or periodic error found on this file, are then the logging's, not the plant's: log at the "
                    "reading's own rate, or keep only the rows where it changed.");
    }
  }

  // Rows piled at the extreme readings of a noisy channel: a saturated transducer or a logger's range.
  if (noise_sigma_pa > kClipMinNoisePa) {
    const auto piled = [&](std::size_t n, double p, const char* which) {
      if (n < kPiledMinRows || static_cast<double>(n) < kPiledShare * static_cast<double>(rows_)) return;
      out.push_back("Log: " + text::num(100.0 * static_cast<double>(n) / static_cast<double>(rows_), 3) +
                    " % of rows read exactly " + text::num(p / mpa, 6) + " MPa, the file's " + which +
                    " reading, although the reading is noisy: a saturated transducer or a logger's range. Those rows "
                    "say only that the pressure was " +
                    (which[0] == 'h' ? "at least" : "at most") + " that; an effect fitted to them fits the clipping.");
    };
    piled(at_max_, p_max_pa_, "highest");
    piled(at_min_, p_min_pa_, "lowest");
  }

  // Beyond the model's reach: another unit (bar, psi, kPa for MPa) or another model.
  const double mean_pa = sum_p_pa_ / static_cast<double>(rows_);
  if (std::isfinite(model_lo_pa_) && std::isfinite(model_hi_pa_) && model_hi_pa_ > model_lo_pa_ &&
      (mean_pa > 2 * model_hi_pa_ || mean_pa < 0.5 * model_lo_pa_)) {
    out.push_back("Log: the measured pressure averages " + text::num(mean_pa / mpa, 4) + " MPa, " +
                  (mean_pa > model_hi_pa_ ? "far above" : "far below") + " what the model makes at any valve angle (" +
                  text::num(model_lo_pa_ / mpa, 4) + " to " + text::num(model_hi_pa_ / mpa, 4) +
                  " MPa): is p_meas_mpa in MPa (not bar, psi or kPa), and is this the rig's model? Parameters fitted to "
                  "such a file only stretch the model to the numbers.");
  } else if (started_ && std::abs(yhat0_pa_ - p0_pa_) > kStartMisfitShare * std::abs(p0_pa_)) {
    out.push_back("Log: at the measured angle of the first rows (" + text::num(units::rad_to_deg(angle0_rad_), 4) +
                  " deg) the model makes at best " + text::num(yhat0_pa_ / mpa, 4) + " MPa, not the measured " +
                  text::num(p0_pa_ / mpa, 4) +
                  " MPa: an offset of the pressure (gauge against absolute?), angle columns in other units (radians "
                  "for degrees?), a valve offset beyond the gap, or another valve or chamber than the model's.");
  }
  return out;
}

}  // namespace hil::analysis
