// Measurement files for the workbench tests, made at test time (never committed): a closed-loop
// campaign run (bench's simulate_run, controller designed on the nominal plant) in which the
// simulated truth has hidden effects the nominal model lacks. Reference profiles, seeds and
// magnitudes differ from the campaign files in configs/.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
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
};
// A command that moves between lo_deg and hi_deg at speed_deg_s and dwells dwell_s at each end.
std::function<double(double)> command_triangle(double lo_deg, double hi_deg, double speed_deg_s, double dwell_s);
std::filesystem::path make_lab_log(const LabLog& s, const std::filesystem::path& dir);

}  // namespace hil::test
