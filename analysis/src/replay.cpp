#include "hil/analysis/replay.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
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

double Replayer::start(const ReplayStart& s, double gap_rad) {
  // The motor angle is measured; if the model cannot make the measured pressure with it, the
  // valve rests on the flank that comes closest and the misfit shows from the first row on.
  gap_rad_ = gap_rad;
  model_.settle_nearest(state_, s.p0_pa, s.motor0_rad, 0.0, gap_rad);
  last_t_s_ = s.t0_s;
  last_motor_rad_ = s.motor0_rad;  // the first encoder angle, or the first command (never ramped: no encoder)
  burned_kg_ = 0;
  return state_.s.p_meas_pa;
}

double ReplayData::span_s(std::size_t i) const {
  const std::size_t b = segment_begin(i), e = segment_end(i);
  return e > b ? t_s[e - 1] - t_s[b] : 0.0;
}

bool is_event_time(std::string_view effect, std::string_view key) { return effect == "backlash_change" && key == "step_time_s"; }

plant::Plant segment_model(const plant::Plant& model, const ReplayData& data, std::size_t i) {
  if (data.segments.size() < 2) return model;
  plant::Plant out = model;
  for (const auto& effect : model.effects()) {
    auto params = effect->params();
    std::vector<double> values;
    bool moved = false;
    for (const auto& p : params) {
      double v = p.value;
      if (is_event_time(effect->kind(), p.key)) {
        v = std::max(0.0, v - data.segments[i].clock_offset_s);
        moved |= v != p.value;
      }
      values.push_back(v);
    }
    if (moved) out = out.with(effect->with_params(values));
  }
  return out;
}

namespace {

// File m's run record into d's rows from b on (d's other files' rows: nothing left out, no input).
void add_run_inputs(ReplayData& d, const Measurement& m, std::size_t b) {
  const bool left = !m.left_out.empty(), gap = !m.run.gap.empty();
  if ((left || !d.left_out.empty()) && d.left_out.size() < b) d.left_out.resize(b, 0);
  if ((gap || !d.gap_rad.empty()) && d.gap_rad.size() < b) d.gap_rad.resize(b, plant::kNaN);
  if (left) {
    d.left_out.insert(d.left_out.end(), m.left_out.begin(), m.left_out.end());
    d.rows_left_out += m.run.rows_left_out();
  } else if (!d.left_out.empty()) {
    d.left_out.resize(d.size(), 0);
  }
  if (gap) {
    // The step to row k runs from t[k-1]: the input in force then.
    d.gap_rad.push_back(m.run.gap_at(m.rows.t_s[0]));
    for (std::size_t k = 1; k < m.rows.size(); ++k) d.gap_rad.push_back(m.run.gap_at(m.rows.t_s[k - 1]));
  } else if (!d.gap_rad.empty()) {
    d.gap_rad.resize(d.size(), plant::kNaN);
  }
}

}  // namespace

ReplayData replay_data(const Measurement& m) { return replay_data(std::vector<const Measurement*>{&m}); }

ReplayData replay_data(const std::vector<const Measurement*>& files) {
  if (files.empty()) throw std::invalid_argument("replay_data: no file");
  ReplayData d;
  d.segments.clear();
  const bool enc = !files.front()->rows.theta_motor_rad.empty();
  for (const Measurement* m : files) {
    const auto& r = m->rows;
    if (r.size() == 0) throw std::invalid_argument("replay_data: a file without rows");
    if (r.theta_motor_rad.empty() == enc)
      throw std::invalid_argument("replay_data: files with and without the encoder column cannot be replayed together");
    const std::size_t b = d.size();
    const double offset =
        d.segments.empty() ? 0.0 : d.segments.back().clock_offset_s + d.span_s(d.segments.size() - 1) + ReplayData::kRunPauseS;
    d.segments.push_back({b, estimate_start(r), offset});
    d.t_s.insert(d.t_s.end(), r.t_s.begin(), r.t_s.end());
    d.y_pa.insert(d.y_pa.end(), r.p_meas_pa.begin(), r.p_meas_pa.end());
    d.motor_rad.insert(d.motor_rad.end(), r.theta_motor_rad.begin(), r.theta_motor_rad.end());
    d.cmd_held_rad.push_back(r.theta_cmd_rad[0]);
    for (std::size_t k = 1; k < r.size(); ++k) d.cmd_held_rad.push_back(r.theta_cmd_rad[k - 1]);
    add_run_inputs(d, *m, b);
  }
  return d;
}

ReplayData decimate(const ReplayData& full, std::size_t m) {
  if (m <= 1) return full;
  ReplayData d;
  d.segments.clear();
  d.decimation = full.decimation * m;
  const bool enc = !full.motor_rad.empty();
  for (std::size_t i = 0; i < full.segments.size(); ++i) {
    const std::size_t b = full.segment_begin(i), n = full.segment_end(i);
    d.segments.push_back({d.size(), full.segments[i].start, full.segments[i].clock_offset_s});
    for (std::size_t k = b; k < n; k += m) {
      d.t_s.push_back(full.t_s[k]);
      d.y_pa.push_back(full.y_pa[k]);
      if (!full.left_out.empty()) d.rows_left_out += full.left_out[k], d.left_out.push_back(full.left_out[k]);
      if (!full.gap_rad.empty()) d.gap_rad.push_back(full.gap_rad[k > b ? k - m + 1 : k]);
      if (enc) d.motor_rad.push_back(full.motor_rad[k]);
      if (k == b) {
        d.cmd_held_rad.push_back(full.cmd_held_rad[b]);
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
  }
  return d;
}

bool replay(const plant::Plant& model, const ReplayData& data, std::span<double> yhat) {
  const bool enc = !data.motor_rad.empty();
  for (std::size_t i = 0; i < data.segments.size(); ++i) {
    const std::size_t b = data.segment_begin(i), e = data.segment_end(i);
    if (e <= b) continue;
    std::optional<plant::Plant> moved;  // several files: this one's event times
    if (data.segments.size() > 1) moved = segment_model(model, data, i);
    Replayer r(moved ? *moved : model);
    const bool gap = !data.gap_rad.empty();
    try {
      yhat[b] = r.start(data.segments[i].start, gap ? data.gap_rad[b] : plant::kNaN);
    } catch (const std::out_of_range&) {
      return false;
    }
    // A decimated copy holds the mean command of the rows it replaces (decimate): its steps are held.
    const bool interpolate = data.decimation == 1;
    for (std::size_t k = b + 1; k < e; ++k) {
      const double motor = enc ? data.motor_rad[k] : plant::kNaN;
      if (gap) r.set_gap(data.gap_rad[k]);
      if (interpolate) {
        // The command logged at row k is held over the next step; the last row's is not kept (nothing follows it).
        const double cmd_row = k + 1 < e ? data.cmd_held_rad[k + 1] : data.cmd_held_rad[k];
        yhat[k] = r.advance_interpolated(data.t_s[k], data.cmd_held_rad[k], cmd_row, motor);
      } else {
        yhat[k] = r.advance(data.t_s[k], data.cmd_held_rad[k], motor);
      }
    }
    for (std::size_t k = b; k < e; k += 97) {
      if (!std::isfinite(yhat[k])) return false;
    }
    if (!std::isfinite(yhat[e - 1])) return false;
  }
  // Rows left out are predicted as measured: every residual, sum and fit sees 0 there.
  for (std::size_t k = 0; k < data.left_out.size(); ++k)
    if (data.left_out[k]) yhat[k] = data.y_pa[k];
  return true;
}

}  // namespace hil::analysis
