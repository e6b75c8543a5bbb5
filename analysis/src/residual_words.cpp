// The residual analyser's words: where in time the error lives (segments), and the signature.
#include "residual_analyzer.hpp"

namespace hil::analysis {

// Binary segmentation of the windows' mean square (see kChangeRmsRatio). Windows with fewer than
// a quarter of the fullest window's samples (a dropout) join their neighbours.
void residual_detail::find_segments(ResidualReport& r) {
  const auto& w = r.windows;
  if (w.empty()) return;
  std::size_t max_samples = 0;
  for (const auto& x : w) max_samples = std::max(max_samples, x.error.samples);
  std::vector<double> sum_sq(w.size() + 1, 0.0), count(w.size() + 1, 0.0);  // prefix sums
  for (std::size_t i = 0; i < w.size(); ++i) {
    const double n = static_cast<double>(w[i].error.samples);
    sum_sq[i + 1] = sum_sq[i] + w[i].error.rmse_pa * w[i].error.rmse_pa * n;
    count[i + 1] = count[i] + n;
  }
  auto ms = [&](std::size_t a, std::size_t b) {  // windows [a, b)
    const double n = count[b] - count[a];
    return n > 0 ? (sum_sq[b] - sum_sq[a]) / n : 0.0;
  };
  auto usable = [&](std::size_t i) { return w[i].error.samples * 4 >= max_samples; };
  std::vector<std::size_t> cuts = {0, w.size()};
  while (cuts.size() < kMaxChangePoints + 2) {
    // The best cut over all segments: largest likelihood gain of a piecewise-constant variance.
    double best_gain = 0;
    std::size_t best_cut = 0;
    for (std::size_t s = 0; s + 1 < cuts.size(); ++s) {
      const std::size_t a = cuts[s], b = cuts[s + 1];
      const double n = count[b] - count[a], m = ms(a, b);
      if (m <= 0) continue;
      for (std::size_t c = a + 2; c + 2 <= b; ++c) {
        if (!usable(c) || !usable(c - 1)) continue;
        const double n1 = count[c] - count[a], n2 = count[b] - count[c];
        const double m1 = ms(a, c), m2 = ms(c, b);
        if (m1 <= 0 || m2 <= 0) continue;
        const double ratio = std::sqrt(std::max(m1, m2) / std::min(m1, m2));
        if (ratio < kChangeRmsRatio) continue;
        const double gain = n * std::log(m) - n1 * std::log(m1) - n2 * std::log(m2);
        if (gain > best_gain) best_gain = gain, best_cut = c;
      }
    }
    if (best_cut == 0) break;
    cuts.insert(std::upper_bound(cuts.begin(), cuts.end(), best_cut), best_cut);
  }
  for (std::size_t s = 0; s + 1 < cuts.size(); ++s) {
    ResidualReport::Segment g;
    g.t0_s = w[cuts[s]].t0_s;
    g.t1_s = w[cuts[s + 1] - 1].t1_s;
    g.rmse_pa = std::sqrt(ms(cuts[s], cuts[s + 1]));
    g.at_floor = g.rmse_pa <= kSegmentFloorRatio * r.noise_sigma_pa;
    if (s > 0) r.change_points_s.push_back(g.t0_s);
    r.segments.push_back(g);
  }
}

namespace {

// "Where in time", in words, when the error is confined to part of the run: one sentence, or
// empty when the error is everywhere (or nowhere).
std::string confinement_sentence(const ResidualReport& r) {
  // Neighbouring segments above the floor are one span here (the level may change inside it).
  std::vector<ResidualReport::Segment> g;
  for (const auto& x : r.segments) {
    if (!g.empty() && !g.back().at_floor && !x.at_floor) {
      const double d0 = g.back().t1_s - g.back().t0_s, d1 = x.t1_s - x.t0_s;
      g.back().rmse_pa = std::sqrt((g.back().rmse_pa * g.back().rmse_pa * d0 + x.rmse_pa * x.rmse_pa * d1) / (d0 + d1));
      g.back().t1_s = x.t1_s;
    } else {
      g.push_back(x);
    }
  }
  if (g.size() < 2) return "";
  // The part at the floor must be a real part of the run (a quarter), not a quiet start.
  double floor_s = 0;
  for (const auto& x : g) floor_s += x.at_floor ? x.t1_s - x.t0_s : 0.0;
  if (floor_s < 0.25 * (g.back().t1_s - g.front().t0_s)) return "";
  std::string spans;
  std::size_t failing = 0;
  for (const auto& x : g) {
    if (x.at_floor) continue;
    ++failing;
    spans += (spans.empty() ? "" : ", ") + text::instant(x.t0_s) + "-" + text::instant(x.t1_s) + " s";
  }
  const double kpa = units::kPaPerKpa;
  const bool first_bad = !g.front().at_floor, last_bad = !g.back().at_floor;
  if (failing == 1 && !first_bad && !last_bad) {
    const ResidualReport::Segment* bad = nullptr;
    for (const auto& x : g)
      if (!x.at_floor) bad = &x;
    return "The error is confined to " + text::instant(bad->t0_s) + "-" + text::instant(bad->t1_s) + " s" +
           fmt(" (RMS %.3g kPa there); before and after it is at the noise floor: something changed at ", bad->rmse_pa / kpa) +
           text::instant(bad->t0_s) + " s and recovered at " + text::instant(bad->t1_s) + " s.";
  }
  if (failing == 1 && last_bad) {
    return "The error starts at " + text::instant(g.back().t0_s) +
           fmt(" s (RMS %.3g kPa after it); before it the model is at the noise floor: something changed at ",
               g.back().rmse_pa / kpa) +
           text::instant(g.back().t0_s) + " s and did not recover before the end of the file.";
  }
  if (failing == 1 && first_bad) {
    return "The error is confined to the start of the run, up to " + text::instant(g.front().t1_s) +
           fmt(" s (RMS %.3g kPa); after it the model is at the noise floor.", g.front().rmse_pa / kpa);
  }
  return "The error comes and goes: above the noise in " + spans + "; at the noise floor in between.";
}

}  // namespace

void ResidualAnalyzer::Impl::describe(ResidualReport& r) {
  auto& out = r.signature;
  const double kpa = units::kPaPerKpa;
  const double rmse = r.error.rmse_pa, sigma = r.noise_sigma_pa;
  if (r.rows == 0) return;
  if (at_noise_floor(rmse, sigma)) {
    out.push_back(fmt("At the noise floor: RMS error %.3g kPa against measurement noise %.3g kPa.", rmse / kpa, sigma / kpa));
  } else {
    out.push_back(
        fmt("RMS error %.3g kPa is %.3g times the measurement noise (%.3g kPa).", rmse / kpa, rmse / sigma, sigma / kpa));
  }
  // A filtered transducer's noise is correlated over a few rows by itself: say so, so that a short
  // residual correlation time is read as the noise's, not as a missing effect.
  if (r.noise.coloured()) {
    const double tau_ms = r.noise.correlation_time_samples() * r.diagnostics.dt_s * 1e3;
    std::string corner = r.noise.corner_hz() > 0 ? fmt(", corner %.3g Hz: an anti-alias filter?", r.noise.corner_hz()) : "";
    out.push_back(
        fmt("The measurement noise is coloured: %.3g kPa of first-order noise (pole %.3g per row",
            r.noise.coloured_sigma_pa / kpa, r.noise.phi) +
        corner +
        fmt(") and %.3g kPa white; by itself it keeps the residual correlated for about ", r.noise.white_sigma_pa / kpa) +
        fmt("%.3g ms.", tau_ms));
  }
  if (std::abs(r.error.bias_pa) > 0.5 * rmse && rmse > 1.5 * sigma) {
    out.push_back(
        fmt("Mostly a constant offset: bias %+.3g kPa (measured above the model when positive).", r.error.bias_pa / kpa));
  }
  // Regimes: the one where the error is largest relative to the whole.
  const Regime* worst = nullptr;
  for (const auto& g : r.regimes) {
    if (g.share < 0.02 || g.error.samples < 20) continue;
    if (worst == nullptr || g.error.rmse_pa > worst->error.rmse_pa) worst = &g;
  }
  auto find = [&](const char* name) -> const Regime* {
    for (const auto& g : r.regimes)
      if (g.name == name) return &g;
    return nullptr;
  };
  const std::string confined = rmse > 1.5 * sigma ? confinement_sentence(r) : "";
  if (!confined.empty()) {
    // Regime shares over the whole run would mislead when the error lives in one span of it.
    out.push_back(confined);
  } else if (worst != nullptr && worst->error.rmse_pa > 1.3 * rmse && rmse > 1.5 * sigma) {
    char b[300];
    std::snprintf(b, sizeof b, "Largest in regime '%s' (%s): RMS %.3g kPa against %.3g kPa overall.", worst->name.c_str(),
                  worst->description.c_str(), worst->error.rmse_pa / kpa, rmse / kpa);
    out.push_back(b);
  } else if (rmse > 1.5 * sigma) {
    out.push_back("Spread evenly over the motion and pressure regimes (no regime's RMS is 1.3x the overall).");
  }
  const Regime *early = find("early"), *late = find("late");
  if (early && late && rmse > 1.5 * sigma && early->error.samples && late->error.samples) {
    const double ratio = late->error.rmse_pa / std::max(early->error.rmse_pa, 1.0);
    if (ratio > 1.5)
      out.push_back(fmt("Grows over the run: RMS %.3g kPa in the first half, %.3g kPa in the second (a drift).",
                        early->error.rmse_pa / kpa, late->error.rmse_pa / kpa));
    else if (ratio < 1 / 1.5)
      out.push_back(fmt("Shrinks over the run: RMS %.3g kPa in the first half, %.3g kPa in the second.",
                        early->error.rmse_pa / kpa, late->error.rmse_pa / kpa));
  }
  const Diagnostics& d = r.diagnostics;
  for (const auto& pk : d.peaks) {
    if (pk.power_share < 0.05) continue;
    out.push_back(fmt("Spectrum: %.0f %% of the residual power in a peak at %.3g Hz", 100 * pk.power_share, pk.hz) + ": " +
                  pk.name + ".");
  }
  if (rmse > 1.5 * sigma && d.angle_ripple_period_deg > 0) {
    out.push_back(
        fmt("Periodic in the drive angle (the encoder's, or the command's without one): a ripple of %.3g kPa with a "
            "%.3g deg period (%.0f %% of the residual's variation with the angle once slower trends are removed): a "
            "gear or coupling error (one period per tooth or per turn)? No candidate holds it: write it as an effect.",
            d.angle_ripple_kpa, d.angle_ripple_period_deg, 100 * d.angle_ripple_share));
  }
  if (rmse > 1.5 * sigma && d.velocity_band_deg_s > 0 && d.velocity_band_flips) {
    out.push_back(
        fmt("Against the drive velocity: a misfit that flips with the direction of motion, at |velocity| < %.3g "
            "deg/s already (",
            d.velocity_band_deg_s) +
        fmt("mean %+.3g kPa while opening, %+.3g kPa while closing; ", d.velocity_band_opening_kpa, d.velocity_band_closing_kpa) +
        fmt("%.0f %% of the excess error power): stick-slip (a valve that sticks until the drive winds it up) "
            "or a play the model lacks? When no candidate explains it, write it as an effect.",
            100 * d.velocity_band_excess_share));
  } else if (rmse > 1.5 * sigma && d.velocity_band_deg_s > 0) {
    out.push_back(fmt("Against the drive velocity: a misfit concentrated at |velocity| < %.3g deg/s (", d.velocity_band_deg_s) +
                  fmt("%.0f %% of the excess error power in %.0f %% of the rows; ", 100 * d.velocity_band_excess_share,
                      100 * d.velocity_band_rows_share) +
                  fmt("RMS %.3g kPa there, %.3g kPa elsewhere): ", d.velocity_band_rms_kpa, d.velocity_outside_rms_kpa) +
                  "stick-slip (a valve that sticks until the drive winds up) or a play the model lacks? When no "
                  "candidate explains it, write it as an effect.");
  }
  if (rmse > 1.5 * sigma && d.low_frequency_share > 0.5) {
    out.push_back(fmt("Slow: %.0f %% of the residual power lies below 0.5 Hz (static or slowly varying error).",
                      100 * d.low_frequency_share));
  }
  if (d.white) {
    out.push_back("Residual is white (autocorrelation inside the 99 % bounds).");
  } else {
    out.push_back(fmt("Residual is correlated: %.0f %% of lags outside the 99 %% bounds, correlation time %.3g s.",
                      100 * d.acf_outside_share, d.tau_int_samples * d.dt_s));
  }
  if (!d.xcf.empty()) {
    if (d.input_correlated) {
      // Which leads says something only for a clear correlation that no periodic peak dominates
      // (two signals oscillating together correlate at every lag).
      bool periodic = false;
      for (const auto& pk : d.peaks) periodic |= pk.power_share > 0.3;
      std::string why = ".";
      if (d.xcf_max_abs >= 0.2 && !periodic) {
        why = d.xcf_max_lag_s < 0 ? ": the drive follows the residual (the controller reacting to what the model lacks)."
                                  : ": the residual follows the drive (the model answers the drive's motion wrongly).";
      }
      out.push_back(fmt("Correlated with the drive motion: peak cross-correlation %.2f at lag %+.0f ms (bound %.2g)",
                        d.xcf_max_abs, 1e3 * d.xcf_max_lag_s, d.xcf_bound) +
                    why);
    } else {
      out.push_back("Not correlated with the drive motion (cross-correlation inside the 99 % bounds).");
    }
  }
}

}  // namespace hil::analysis
