// A campaign: a plant, a reference profile, a programmed gap, and one or more controller runs to
// compare, loaded from YAML (configs/campaigns/*.yaml, documented in place). Everything is
// validated at load: a typo, a wrong type, a missing field or a physically impossible value
// (dT <= 0, gap < 0, a reference outside the plant's reach, ...) throws cfg::Error naming
// file, line and key, before anything runs or is written.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "hil/bench/campaign/checks.hpp"
#include "hil/bench/rt/loop_input.hpp"
#include "hil/bench/rt/schedule.hpp"
#include "hil/ctl/controller.hpp"
#include "hil/plant/plant.hpp"

namespace hil::cfg {
class Node;
}

namespace hil::bench {

// A control period's range in ms, 100 kHz to 1 Hz: a campaign's period_ms, and `hilbench plant
// --period-ms` (unbounded, 1e13 overflowed the plant's clock and 1e-12 busy-spun a core).
inline constexpr double kMinPeriodMs = 0.01;
inline constexpr double kMaxPeriodMs = 1000;

// The loop's programme (plant, duration, period, seed, reference and gap schedules: rt/loop_input.hpp)
// with what makes it a campaign.
struct Campaign : LoopProgramme {
  std::string name;
  std::string description;
  std::filesystem::path file;
  std::filesystem::path plant_file;
  double sensor_noise_rms_pa = 0;   // as the plant's transducer has it
  std::vector<double> reversals_s;  // reference reversals (the first movement is reversal 1)
  long reference_moves = 0;         // steps and ramps of the reference, either direction
  std::vector<RunSpec> runs;
  std::vector<CheckSpec> checks;  // the campaign's verdicts (checks.hpp); empty: none asked
  std::string yaml_text;          // the file as loaded, for the run's snapshot
  std::string plant_yaml_text;    // the plant file as loaded, for the run's snapshot
  // Other files the campaign read (a csv reference item's file): a sweep's plan fingerprints
  // their contents, since every point reads them again.
  std::vector<std::filesystem::path> data_files;
};

Campaign load_campaign(const std::filesystem::path& file);
// For YAML posted over the API: `origin` names it in errors; relative paths resolve from `base_dir`.
// A non-empty `plants_root` confines the plant file to that folder (the bench's configs).
Campaign load_campaign_text(const std::string& yaml, const std::string& origin, const std::filesystem::path& base_dir,
                            const std::filesystem::path& plants_root = {});
// A campaign and its plant both from YAML text (a sweep's point, edited in memory): the campaign's
// `plant:` key is not opened; `plant_origin` names the plant text in errors and is the plant_file.
Campaign load_campaign_text(const std::string& yaml, const std::string& origin, const std::filesystem::path& base_dir,
                            const std::string& plant_yaml, const std::filesystem::path& plant_origin);

// The same campaign with another transducer noise (0 reproduces the paper's noise-free
// simulation). The controllers keep what they were told of the transducer.
Campaign with_sensor_noise(Campaign c, double noise_rms_kpa);

// The controller's design model from a plant (its gas_generator and throat_map blocks).
ctl::ChamberModel chamber_model_of(const plant::Plant& plant);

}  // namespace hil::bench
