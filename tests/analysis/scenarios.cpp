#include "scenarios.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <memory>
#include <stdexcept>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/sim.hpp"
#include "hil/config.hpp"
#include "hil/csv_writer.hpp"
#include "hil/plant/registry.hpp"
#include "hil/units.hpp"

namespace hil::test {

std::filesystem::path nominal_model() { return std::filesystem::path(HIL_SOURCE_DIR) / "configs/plant/nominal.yaml"; }

std::string reference_square(double low, double high, double half, double from) {
  char b[300];
  std::snprintf(b, sizeof b,
                "  initial_mpa: %g\n  profile:\n    - square: {from_s: %g, half_period_s: %g, low_mpa: %g, high_mpa: %g}\n", low,
                from, half, low, high);
  return b;
}

std::string reference_random(std::uint64_t seed, double lo, double hi, double dwell_lo, double dwell_hi) {
  char b[300];
  std::snprintf(b, sizeof b,
                "  initial_mpa: %g\n  profile:\n    - random: {seed: %llu, from_s: 1.0, min_mpa: %g, max_mpa: %g, "
                "dwell_s: [%g, %g], ramp_probability: 0.4, ramp_s: [0.3, 1.5], min_change_mpa: 0.12}\n",
                0.5 * (lo + hi), static_cast<unsigned long long>(seed), lo, hi, dwell_lo, dwell_hi);
  return b;
}

std::string reference_ramps(double low, double high, double period, double duration) {
  std::string s = "  initial_mpa: " + std::to_string(low) + "\n  profile:\n";
  char b[200];
  for (double t = 1.0; t + period <= duration; t += period) {
    std::snprintf(b, sizeof b, "    - ramp: {from_s: %g, to_s: %g, to_mpa: %g}\n", t, t + 0.4 * period, high);
    s += b;
    std::snprintf(b, sizeof b, "    - ramp: {from_s: %g, to_s: %g, to_mpa: %g}\n", t + 0.5 * period, t + 0.9 * period, low);
    s += b;
  }
  return s;
}

plant::Plant with_block(const plant::Plant& p, const std::string& kind, const std::string& body_yaml) {
  const plant::EffectInfo* info = plant::find_effect(kind);
  if (info == nullptr) throw std::invalid_argument("no effect " + kind);
  return p.with(info->from_yaml(cfg::Node::load_string(body_yaml, kind)));
}

plant::Plant with_param(const plant::Plant& p, const std::string& kind, const std::string& key, double value) {
  const plant::Effect* e = p.find(kind);
  if (e == nullptr) throw std::invalid_argument("no block " + kind);
  std::vector<double> v;
  for (const auto& q : e->params()) v.push_back(q.key == key ? value : q.value);
  return p.with(e->with_params(v));
}

std::filesystem::path make_measurement(const Scenario& s, const std::filesystem::path& dir) {
  std::string yaml = "name: " + s.name + "\nplant: " + nominal_model().string() +
                     "\nduration_s: " + std::to_string(s.duration_s) + "\nperiod_ms: 1\nseed: " + std::to_string(s.seed) +
                     "\nsensor_noise_kpa: " + std::to_string(s.noise_kpa) + "\nreference:\n" + s.reference_yaml +
                     "controller:\n  observer: robust\nruns:\n  - name: run\n    compensation: " + s.compensation + "\n";
  bench::Campaign c = bench::load_campaign_text(yaml, s.name + ".yaml", dir);
  c.plant = std::make_shared<const plant::Plant>(s.truth(*c.plant));  // the controller stays nominal

  std::vector<CsvColumn> cols = {{"t_s", 4}, {"theta_cmd_deg", 5}, {"p_meas_mpa", 6}};
  if (s.extra_columns) cols.insert(cols.begin() + 1, {"lab_temperature_c", 2});
  if (s.encoder) cols.push_back({"theta_motor_deg", 5});
  if (s.reference_column) cols.push_back({"p_ref_mpa", 6});
  if (s.extra_columns) cols.push_back({"valve_current_a", 3});
  const auto file = dir / (s.name + ".csv");
  CsvWriter w(file, cols, {{"source", "hilbench tests (hidden effects)"}, {"scenario", s.name}});
  std::vector<double> row;
  bench::simulate_run(c, c.runs.front(), [&](const bench::TelemetryRecord& rec) {
    const bench::StepRecord& r = rec.step;
    row.clear();
    row.push_back(r.t_s);
    if (s.extra_columns) row.push_back(21.5);
    row.push_back(units::rad_to_deg(r.theta_cmd_rad));
    row.push_back(units::pa_to_mpa(r.p_meas_pa));
    if (s.encoder) row.push_back(units::rad_to_deg(r.theta_motor_rad));
    if (s.reference_column) row.push_back(units::pa_to_mpa(r.p_ref_pa));
    if (s.extra_columns) row.push_back(1.25);
    w.row(row);
  });
  w.close();
  return file;
}

std::function<double(double)> command_triangle(double lo_deg, double hi_deg, double speed_deg_s, double dwell_s) {
  const double move_s = (hi_deg - lo_deg) / speed_deg_s;
  const double period_s = 2 * (move_s + dwell_s);
  return [=](double t) {
    const double ph = std::fmod(t, period_s);
    if (ph < dwell_s) return lo_deg;
    if (ph < dwell_s + move_s) return lo_deg + speed_deg_s * (ph - dwell_s);
    if (ph < 2 * dwell_s + move_s) return hi_deg;
    return hi_deg - speed_deg_s * (ph - 2 * dwell_s - move_s);
  };
}

std::filesystem::path make_lab_log(const LabLog& s, const std::filesystem::path& dir) {
  const plant::Plant nominal = plant::Plant::load(nominal_model());
  plant::Plant truth = s.truth(with_param(nominal, "pressure_sensor", "noise_rms_kpa", s.noise_kpa));
  plant::PlantState st = truth.make_state(s.seed);
  plant::Rng jitter(s.seed + 1);
  // Default command: 11 deg (about 1 MPa) with steps every 2.7 s, ramps, and a slow sine on top.
  auto default_command_deg = [](double t) {
    const double steps[] = {11.0, 8.0, 13.0, 9.5, 6.5, 12.0, 10.0};
    const double base = steps[static_cast<int>(t / 2.7) % 7];
    const double ramp = std::fmod(t, 9.0) < 1.5 ? 0.8 * std::fmod(t, 9.0) : 0.0;
    return base + ramp + 0.6 * std::sin(2 * 3.141592653589793 * 0.13 * t);
  };
  const std::function<double(double)> command_deg = s.command_deg ? s.command_deg : default_command_deg;
  // Logging starts in a steady state: the motor at the first command, the valve on a flank.
  truth.settle_nearest(st, 0.0, units::deg_to_rad(command_deg(0)), std::isnan(s.plant_t0_s) ? s.t0_s : s.plant_t0_s);
  const auto file = dir / (s.name + ".csv");
  std::FILE* f = std::fopen(file.c_str(), "wb");
  if (f == nullptr) throw std::runtime_error("cannot write " + file.string());
  std::fprintf(f, "# logger: LabX DAQ-7\r\n# operator: someone else\r\n");
  std::fprintf(f, "p_meas_mpa,status,t_s,temperature_c,theta_cmd_deg%s\r\n", s.encoder ? ",theta_motor_deg" : "");
  double t = s.t0_s;
  while (t < s.t0_s + s.duration_s) {
    const double cmd = units::deg_to_rad(command_deg(t - s.t0_s));  // theta_cmd(k), held until the next row
    const bool in_hole = std::any_of(s.holes_s.begin(), s.holes_s.end(), [&](const std::pair<double, double>& h) {
      return t - s.t0_s >= h.first && t - s.t0_s < h.second;
    });
    if (!in_hole) {
      std::fprintf(f, "%.6f,OK,%.6f,%.2f,%.5f", units::pa_to_mpa(st.s.p_meas_pa), t, 21.0 + 0.01 * (t - s.t0_s),
                   units::rad_to_deg(cmd));
      if (s.encoder) std::fprintf(f, ",%.5f", units::rad_to_deg(st.s.theta_motor_rad));
      std::fprintf(f, "\r\n");
    }
    const double dt = 1e-3 * (0.7 + 0.6 * jitter.uniform());
    truth.step(st, {cmd, plant::kNaN, plant::kNaN}, dt);
    t += dt;
  }
  std::fclose(f);
  return file;
}

double SensorNoise::total_kpa() const {
  return std::sqrt(coloured_kpa * coloured_kpa + white_kpa * white_kpa + step_kpa * step_kpa / 12);
}

void add_sensor_noise(const std::filesystem::path& csv, const SensorNoise& n) {
  std::ifstream in(csv, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + csv.string());
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  in.close();
  auto split = [](const std::string& line) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) cells.push_back(c);
    return cells;
  };
  std::size_t header = 0;
  while (header < lines.size() && !lines[header].empty() && lines[header][0] == '#') ++header;
  if (header >= lines.size()) throw std::runtime_error(csv.string() + ": no header");
  auto strip = [](std::string c) {
    while (!c.empty() && (c.back() == '\r' || c.back() == ' ')) c.pop_back();
    return c;
  };
  const auto names = split(lines[header]);
  std::size_t col_t = names.size(), col_p = names.size();
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (strip(names[i]) == "t_s") col_t = i;
    if (strip(names[i]) == "p_meas_mpa") col_p = i;
  }
  if (col_t == names.size() || col_p == names.size()) throw std::runtime_error(csv.string() + ": no t_s or p_meas_mpa");
  std::mt19937_64 rng(n.seed);
  std::normal_distribution<double> g(0, 1);
  double x_kpa = n.coloured_kpa * g(rng);  // stationary from the first row
  double t_prev = std::nan("");
  std::ofstream out(csv, std::ios::binary | std::ios::trunc);
  for (std::size_t li = 0; li < lines.size(); ++li) {
    if (li <= header || lines[li].empty()) {
      out << lines[li] << '\n';
      continue;
    }
    const bool crlf = lines[li].back() == '\r';
    auto cells = split(crlf ? lines[li].substr(0, lines[li].size() - 1) : lines[li]);
    const double t = std::stod(cells[col_t]);
    const double dt = std::isfinite(t_prev) ? t - t_prev : 0;
    t_prev = t;
    const double phi = n.filter_hz > 0 ? std::exp(-2 * 3.141592653589793 * n.filter_hz * dt) : n.phi;
    if (dt > 0) x_kpa = phi * x_kpa + std::sqrt(1 - phi * phi) * n.coloured_kpa * g(rng);
    double v_mpa = std::stod(cells[col_p]) + 1e-3 * (x_kpa + n.white_kpa * g(rng));
    if (n.step_kpa > 0) v_mpa = 1e-3 * n.step_kpa * std::round(v_mpa / (1e-3 * n.step_kpa));
    char b[40];
    std::snprintf(b, sizeof b, "%.7f", v_mpa);
    cells[col_p] = b;
    for (std::size_t i = 0; i < cells.size(); ++i) out << (i ? "," : "") << cells[i];
    out << (crlf ? "\r\n" : "\n");
  }
  if (!out) throw std::runtime_error("cannot write " + csv.string());
}

}  // namespace hil::test
