#include "hil/analysis/replay.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hil::analysis {

ReplayStart estimate_start(const MeasurementRows& rows, double settle_s) {
  if (rows.size() == 0) throw std::invalid_argument("estimate_start: no rows");
  ReplayStart s;
  s.t0_s = rows.t_s[0];
  s.motor0_rad = rows.theta_motor_rad.empty() ? rows.theta_cmd_rad[0] : rows.theta_motor_rad[0];
  double sum = 0;
  std::size_t n = 0;
  for (; n < rows.size() && (n == 0 || rows.t_s[n] - s.t0_s < settle_s); ++n) sum += rows.p_meas_pa[n];
  s.p0_pa = sum / static_cast<double>(n);
  s.rows_averaged = n;
  return s;
}

plant::Plant noise_free(const plant::Plant& model) {
  return model.find("pressure_sensor") ? model.without("pressure_sensor") : model;
}

double Replayer::start(const ReplayStart& s) {
  // The motor angle is measured; if the model cannot make the measured pressure with it, the
  // valve rests on the flank that comes closest and the misfit shows from the first row on.
  model_.settle_nearest(state_, s.p0_pa, s.motor0_rad, 0.0);
  last_t_s_ = s.t0_s;
  burned_kg_ = 0;
  return state_.s.p_meas_pa;
}

ReplayData replay_data(const Measurement& m) {
  ReplayData d;
  const auto& r = m.rows;
  d.t_s = r.t_s;
  d.y_pa = r.p_meas_pa;
  d.cmd_held_rad.resize(r.size());
  for (std::size_t k = 1; k < r.size(); ++k) d.cmd_held_rad[k] = r.theta_cmd_rad[k - 1];
  if (!r.theta_cmd_rad.empty()) d.cmd_held_rad[0] = r.theta_cmd_rad[0];
  d.motor_rad = r.theta_motor_rad;
  d.start = estimate_start(r);
  return d;
}

ReplayData decimate(const ReplayData& full, std::size_t m) {
  if (m <= 1) return full;
  ReplayData d;
  d.start = full.start;
  d.decimation = full.decimation * m;
  const std::size_t n = full.size();
  const bool enc = !full.motor_rad.empty();
  for (std::size_t k = 0; k < n; k += m) {
    d.t_s.push_back(full.t_s[k]);
    d.y_pa.push_back(full.y_pa[k]);
    if (enc) d.motor_rad.push_back(full.motor_rad[k]);
    if (k == 0) {
      d.cmd_held_rad.push_back(full.cmd_held_rad[0]);
      continue;
    }
    // Time-weighted mean of the commands held over (t[k-m], t[k]].
    double sum = 0, span = 0;
    for (std::size_t j = k - m + 1; j <= k; ++j) {
      const double dt = full.t_s[j] - full.t_s[j - 1];
      sum += full.cmd_held_rad[j] * dt;
      span += dt;
    }
    d.cmd_held_rad.push_back(sum / span);
  }
  return d;
}

bool replay(const plant::Plant& model, const ReplayData& data, std::span<double> yhat) {
  Replayer r(model);
  try {
    yhat[0] = r.start(data.start);
  } catch (const std::out_of_range&) {
    return false;
  }
  const bool enc = !data.motor_rad.empty();
  for (std::size_t k = 1; k < data.size(); ++k) {
    yhat[k] = r.advance(data.t_s[k], data.cmd_held_rad[k], enc ? data.motor_rad[k] : plant::kNaN);
  }
  for (std::size_t k = 0; k < data.size(); k += 97) {
    if (!std::isfinite(yhat[k])) return false;
  }
  return std::isfinite(yhat[data.size() - 1]);
}

}  // namespace hil::analysis
