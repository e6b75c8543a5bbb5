#include "json_out.hpp"

#include <cmath>
#include <stdexcept>

#include "hil/analysis/compare.hpp"
#include "hil/report/report.hpp"
#include "hil/units.hpp"
#include "text.hpp"

namespace hil::analysis::detail {
namespace {

constexpr double kKpa = units::kPaPerKpa;

// JSON has no NaN: write null.
nlohmann::json number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json stats_json(const ErrorStats& e) {
  return {{"samples", e.samples},
          {"rmse_kpa", number(e.rmse_pa / kKpa)},
          {"bias_kpa", number(e.bias_pa / kKpa)},
          {"max_abs_kpa", number(e.max_abs_pa / kKpa)},
          {"t_at_max_s", number(e.t_at_max_s)}};
}

nlohmann::json numbers(const std::vector<double>& v, double scale = 1) {
  nlohmann::json a = nlohmann::json::array();
  for (double x : v) a.push_back(number(x * scale));
  return a;
}

nlohmann::json binned_json(const Binned& b) {
  nlohmann::json samples = nlohmann::json::array();
  for (auto s : b.samples) samples.push_back(s);
  return {{"quantity", b.quantity},
          {"unit", b.unit},
          {"x", numbers(b.x)},
          {"mean_kpa", numbers(b.mean_pa, 1 / kKpa)},
          {"rms_kpa", numbers(b.rms_pa, 1 / kKpa)},
          {"samples", samples}};
}

}  // namespace

nlohmann::json noise_model_json(const NoiseModel& m) {
  return {{"sigma_kpa", number(m.sigma_pa / kKpa)},
          {"white_kpa", number(m.white_sigma_pa / kKpa)},
          {"coloured_kpa", number(m.coloured_sigma_pa / kKpa)},
          {"phi_per_row", number(m.phi)},
          {"corner_hz", number(m.corner_hz())},
          {"innovation_kpa", number(m.innovation_sigma_pa / kKpa)},
          {"correlation_time_rows", number(m.correlation_time_samples())},
          {"method", m.method}};
}

nlohmann::json residual_to_json(const ResidualReport& r) {
  nlohmann::json j = headline_json(r);
  j["t0_s"] = number(r.t0_s);
  j["noise_method"] = r.noise_method;
  j["noise_model"] = noise_model_json(r.noise);
  j["measured_spread_kpa"] = number(r.y_spread_pa / kKpa);
  nlohmann::json regimes = nlohmann::json::array();
  for (const auto& g : r.regimes) {
    nlohmann::json x = stats_json(g.error);
    x["name"] = g.name;
    x["definition"] = g.description;
    x["share"] = number(g.share);
    regimes.push_back(x);
  }
  j["regimes"] = regimes;
  nlohmann::json windows = nlohmann::json::array();
  for (const auto& w : r.windows) {
    windows.push_back({{"t0_s", number(w.t0_s)},
                       {"t1_s", number(w.t1_s)},
                       {"rmse_kpa", number(w.error.rmse_pa / kKpa)},
                       {"bias_kpa", number(w.error.bias_pa / kKpa)},
                       {"max_abs_kpa", number(w.error.max_abs_pa / kKpa)},
                       {"samples", w.error.samples},
                       {"motion", w.regime}});
  }
  nlohmann::json worst = nlohmann::json::array();
  for (auto i : r.worst) worst.push_back(windows[i]);
  nlohmann::json failing = nlohmann::json::array();
  for (const auto& f : r.failing) failing.push_back({{"t0_s", f.first}, {"t1_s", f.second}});
  j["windows"] = {{"width_s", r.window_width_s}, {"list", windows}};
  j["worst_windows"] = worst;
  j["failing_spans"] = failing;
  nlohmann::json segments = nlohmann::json::array();
  for (const auto& g : r.segments)
    segments.push_back({{"t0_s", number(g.t0_s)},
                        {"t1_s", number(g.t1_s)},
                        {"rmse_kpa", number(g.rmse_pa / kKpa)},
                        {"at_noise_floor", g.at_floor}});
  j["segments"] = segments;
  j["change_points_s"] = r.change_points_s;
  j["reversals"] = r.reversals;
  j["motion_cycle_hz"] = number(r.motion_cycle_hz);
  const Diagnostics& d = r.diagnostics;
  nlohmann::json peaks = nlohmann::json::array();
  for (const auto& p : d.peaks) peaks.push_back({{"hz", p.hz}, {"power_share", p.power_share}, {"name", p.name}});
  j["diagnostics"] = {{"sample_period_s", d.dt_s},
                      {"whiteness",
                       {{"white", d.white},
                        {"bound_99", number(d.acf_bound)},
                        {"share_of_lags_outside", number(d.acf_outside_share)},
                        {"correlation_time_s", number(d.tau_int_samples * d.dt_s)},
                        {"effective_samples", number(d.n_eff)},
                        {"lag_s", numbers(d.acf_lag_s)},
                        {"acf", numbers(d.acf)}}},
                      {"input_correlation",
                       {{"input", "drive-angle increments (encoder if logged, else command)"},
                        {"correlated", d.input_correlated},
                        {"bound_99", number(d.xcf_bound)},
                        {"max_abs", number(d.xcf_max_abs)},
                        {"lag_at_max_s", number(d.xcf_max_lag_s)},
                        {"lag_s", numbers(d.xcf_lag_s)},
                        {"xcf", numbers(d.xcf)}}},
                      {"spectrum",
                       {{"hz", numbers(d.psd_hz)},
                        {"psd_kpa2_per_hz", numbers(d.psd_kpa2_per_hz)},
                        {"peaks", peaks},
                        {"low_frequency_share", number(d.low_frequency_share)}}},
                      {"after_reversal",
                       {{"t_since_s", numbers(d.since_reversal_s)},
                        {"into_opening_mean_kpa", numbers(d.after_opening_mean_pa, 1 / kKpa)},
                        {"into_closing_mean_kpa", numbers(d.after_closing_mean_pa, 1 / kKpa)}}},
                      {"vs_time", binned_json(d.vs_time)},
                      {"vs_burned_mass", binned_json(d.vs_burned)},
                      {"vs_dpdt", binned_json(d.vs_dpdt)},
                      {"vs_pressure", binned_json(d.vs_pressure)},
                      {"vs_drive_angle", binned_json(d.vs_drive_angle)},
                      {"angle_ripple",
                       {{"period_deg", number(d.angle_ripple_period_deg)},
                        {"amplitude_kpa", number(d.angle_ripple_kpa)},
                        {"share", number(d.angle_ripple_share)}}},
                      {"vs_drive_velocity", binned_json(d.vs_drive_velocity)},
                      {"velocity_band",
                       {{"below_deg_s", number(d.velocity_band_deg_s)},
                        {"rms_kpa", number(d.velocity_band_rms_kpa)},
                        {"outside_rms_kpa", number(d.velocity_outside_rms_kpa)},
                        {"rows_share", number(d.velocity_band_rows_share)},
                        {"excess_share", number(d.velocity_band_excess_share)},
                        {"flips_with_direction", d.velocity_band_flips},
                        {"mean_opening_kpa", number(d.velocity_band_opening_kpa)},
                        {"mean_closing_kpa", number(d.velocity_band_closing_kpa)}}}};
  j["signature"] = r.signature;
  j["log_warnings"] = r.log_warnings;
  if (r.motor.present) {
    j["motor_channel"] = {{"what", "encoder - drive model fed with the command (the pressure replay uses the encoder)"},
                          {"rmse_deg", number(r.motor.rmse_deg)},
                          {"bias_deg", number(r.motor.bias_deg)},
                          {"max_abs_deg", number(r.motor.max_abs_deg)},
                          {"t_at_max_s", number(r.motor.t_at_max_s)},
                          {"matches", r.motor.rmse_deg <= kMotorChannelTolDeg}};
  }
  return j;
}

void add_summary_table(report::Document& doc, const ResidualReport& r) {
  doc.table({"fit [%]", "noise floor [%]", "RMSE [kPa]", "max error [kPa]", "at [s]", "bias [kPa]", "noise sigma [kPa]", "rows",
             "duration [s]"},
            {{text::fixed(r.fit_pct, 2), text::fixed(r.noise_floor_fit_pct, 2), text::num(r.error.rmse_pa / kKpa, 4),
              text::num(r.error.max_abs_pa / kKpa, 4), text::instant(r.error.t_at_max_s), text::num(r.error.bias_pa / kKpa, 3),
              text::num(r.noise_sigma_pa / kKpa, 3), std::to_string(r.rows), text::num(r.duration_s, 5)}});
}

std::string summary_text(const ResidualReport& r, const std::string& model_name) {
  std::string s;
  char b[400];
  std::snprintf(b, sizeof b,
                "%s: fit %.2f %% (noise floor %.2f %%), RMSE %.3g kPa, max %.3g kPa at %s s, bias %+.3g kPa, "
                "noise %.3g kPa\n",
                model_name.c_str(), r.fit_pct, r.noise_floor_fit_pct, r.error.rmse_pa / kKpa, r.error.max_abs_pa / kKpa,
                text::instant(r.error.t_at_max_s).c_str(), r.error.bias_pa / kKpa, r.noise_sigma_pa / kKpa);
  s += b;
  s += "  by regime              share   RMSE kPa   bias kPa\n";
  for (const auto& g : r.regimes) {
    std::snprintf(b, sizeof b, "  %-20s %6.1f%% %10.3g %10.3g\n", g.name.c_str(), 100 * g.share, g.error.rmse_pa / kKpa,
                  g.error.bias_pa / kKpa);
    s += b;
  }
  if (!r.worst.empty()) {
    s += "  worst windows:";
    for (std::size_t i = 0; i < std::min<std::size_t>(5, r.worst.size()); ++i) {
      const auto& w = r.windows[r.worst[i]];
      std::snprintf(b, sizeof b, " %s-%s s (%.3g kPa)%s", text::instant(w.t0_s).c_str(), text::instant(w.t1_s).c_str(),
                    w.error.rmse_pa / kKpa, i + 1 < std::min<std::size_t>(5, r.worst.size()) ? "," : "");
      s += b;
    }
    s += "\n";
  }
  for (const auto& line : r.run_notes) s += "  * " + line + "\n";
  for (const auto& line : r.log_warnings) s += "  ! " + line + "\n";
  for (const auto& line : r.signature) s += "  - " + line + "\n";
  return s;
}

}  // namespace hil::analysis::detail

namespace hil::analysis {

nlohmann::json headline_json(const ResidualReport& r) {
  using detail::kKpa, detail::number;
  return {{"rows", r.rows},
          {"duration_s", number(r.duration_s)},
          {"fit_pct", number(r.fit_pct)},
          {"noise_floor_fit_pct", number(r.noise_floor_fit_pct)},
          {"rmse_kpa", number(r.error.rmse_pa / kKpa)},
          {"max_error_kpa", number(r.error.max_abs_pa / kKpa)},
          {"max_error_t_s", number(r.error.t_at_max_s)},
          {"bias_kpa", number(r.error.bias_pa / kKpa)},
          {"noise_sigma_kpa", number(r.noise_sigma_pa / kKpa)},
          {"rows_left_out", r.rows_left_out},
          {"run_notes", r.run_notes}};
}

}  // namespace hil::analysis
