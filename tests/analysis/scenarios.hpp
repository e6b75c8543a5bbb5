// Measurement files for the workbench tests, made at test time (never committed): a closed-loop
// campaign run (bench's simulate_run, controller designed on the nominal plant) in which the
// simulated truth has hidden effects the nominal model lacks. Reference profiles, seeds and
// magnitudes differ from the campaign files in configs/.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "hil/plant/plant.hpp"

namespace hil::test {

struct Scenario {
  std::string name;
  double duration_s = 30;
  std::uint64_t seed = 1;
  double noise_kpa = 2.0;
  std::string reference_yaml;             // the campaign's `reference:` block (indented 2)
  std::string compensation = "adaptive";  // none | constant | adaptive
  bool encoder = true;                    // write theta_motor_deg
  bool reference_column = true;           // write p_ref_mpa
  bool extra_columns = false;             // add columns a reader must ignore
  // Truth = nominal (with the campaign's noise) changed by this.
  std::function<plant::Plant(const plant::Plant&)> truth = [](const plant::Plant& p) { return p; };
};

// Named reference profiles (YAML `reference:` blocks).
std::string reference_square(double low_mpa, double high_mpa, double half_period_s, double from_s = 1.0);
std::string reference_random(std::uint64_t seed, double min_mpa, double max_mpa, double dwell_lo_s, double dwell_hi_s);
std::string reference_ramps(double low_mpa, double high_mpa, double period_s, double duration_s = 30);

// Adds a block given as YAML ("valve_offset: {offset_deg: 1.5}" style: kind and its body).
plant::Plant with_block(const plant::Plant& p, const std::string& kind, const std::string& body_yaml);
// Sets one parameter of an existing block.
plant::Plant with_param(const plant::Plant& p, const std::string& kind, const std::string& key, double value);

// Runs the scenario and writes DIR/<name>.csv; returns its path.
std::filesystem::path make_measurement(const Scenario& s, const std::filesystem::path& dir);

std::filesystem::path nominal_model();

// "Another lab's logger": the plant driven open loop by a command profile (steps, ramps, a slow
// sine) with jittered sample times (dt uniform in [0.7, 1.3] ms), time starting at t0_s, CRLF
// line ends, metadata lines, columns in another order and extra columns (one of them text).
struct LabLog {
  std::string name = "lab";
  double t0_s = 1234.5;
  double duration_s = 30;
  std::uint64_t seed = 7;
  double noise_kpa = 3.0;
  bool encoder = false;
  std::function<plant::Plant(const plant::Plant&)> truth = [](const plant::Plant& p) { return p; };
  // The command [deg] against time since the first row; empty: the steps, ramps and sine above.
  std::function<double(double)> command_deg = {};
  // Spans [from, to) of time since the first row where the logger wrote no row (the plant ran on).
  std::vector<std::pair<double, double>> holes_s = {};
  // The plant's clock at the first row (NaN: t0_s, the logger's): a time-dependent effect (erosion,
  // a drift) counts from it; 0 starts it with the log, as on the bench.
  double plant_t0_s = std::numeric_limits<double>::quiet_NaN();
};
// A command that moves between lo_deg and hi_deg at speed_deg_s and dwells dwell_s at each end.
std::function<double(double)> command_triangle(double lo_deg, double hi_deg, double speed_deg_s, double dwell_s);
std::filesystem::path make_lab_log(const LabLog& s, const std::filesystem::path& dir);

// A real transducer's noise, added to the p_meas_mpa column of a file written noise-free
// (Scenario::noise_kpa = 0, LabLog::noise_kpa = 0): first-order coloured noise (an AR(1) with pole
// `phi` per row, or a first-order anti-alias filter with corner `filter_hz`, exact for any row
// spacing: phi = exp(-2 pi f dt)), plus white noise, then the ADC's steps.
struct SensorNoise {
  double coloured_kpa = 0;  // RMS of the coloured part
  double phi = 0;           // its pole per row (used when filter_hz is 0)
  double filter_hz = 0;     // the anti-alias filter's corner frequency
  double white_kpa = 0;     // RMS of the white part
  double step_kpa = 0;      // quantisation step of the reading (0: none)
  std::uint64_t seed = 1;
  // RMS of the whole noise a perfect model leaves (quantisation error included).
  double total_kpa() const;
};
void add_sensor_noise(const std::filesystem::path& csv, const SensorNoise& n);

}  // namespace hil::test
