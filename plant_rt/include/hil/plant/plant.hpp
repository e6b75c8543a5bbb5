// The plant: an ordered chain of physical effects over one flat state vector. The model is const
// and holds parameters only; all state lives in PlantState, so one Plant serves a campaign, a
// replay of measurements and a fit at the same time.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "hil/plant/effect.hpp"
#include "hil/plant/rng.hpp"
#include "hil/plant/signals.hpp"

namespace hil::cfg {
class Node;
}

namespace hil::plant {

struct PlantState {
  std::vector<double> x;  // every effect's state, concatenated in chain order
  Rng rng;
  Signals s;  // signals at time s.t_s
};

class Plant {
 public:
  // Sorts by stage (stable: effects of one stage keep their order). Requires at least one effect
  // each for motor, transmission, throat and chamber; a second one at such a stage modifies what
  // the first made (a user's stiction after the backlash).
  explicit Plant(std::vector<std::shared_ptr<const Effect>> effects);
  // A plant file: top-level key `effects`, one block per effect name. Errors name file:line:key.
  static Plant from_yaml(const cfg::Node& root);
  static Plant load(const std::filesystem::path& file);

  PlantState make_state(std::uint64_t seed) const;

  // Steady state at time t0_s in which the noise-free measured pressure equals p_meas_pa.
  // theta_cmd_rad NaN: the motor rests in positive contact (it last opened the valve) and the
  // command equals the motor angle. Otherwise the motor sits at theta_cmd_rad and the valve is
  // placed inside the gap where the pressure fits. Throws std::out_of_range when no valve angle
  // reaches the pressure, naming the reachable range.
  // gap_rad: a programmed gap at t0 (NaN: the model's own).
  void settle(PlantState& state, double p_meas_pa, double theta_cmd_rad = kNaN, double t0_s = 0, double gap_rad = kNaN) const;
  // As settle(), but when no valve angle reaches p_meas_pa the valve rests where the pressure
  // comes closest (with theta_cmd_rad given: on the nearer flank of the gap). Returns the
  // noise-free reading reached. For replaying measurements through a model that disagrees with
  // them (analysis/): the motor angle is measured, the pressure is what the model makes of it.
  double settle_nearest(PlantState& state, double p_meas_pa, double theta_cmd_rad = kNaN, double t0_s = 0,
                        double gap_rad = kNaN) const;

  // Advances state.s from t to t + dt_s with inputs held. Real-time safe: noexcept, no
  // allocation, no locking, no I/O.
  void step(PlantState& state, const PlantInputs& in, double dt_s) const noexcept;

  // Noise-free steady pressure range over the valve's travel: {lowest, highest} in Pa.
  std::pair<double, double> pressure_range_pa() const;

  std::span<const std::shared_ptr<const Effect>> effects() const { return effects_; }
  const Effect* find(std::string_view kind) const;
  Plant with(std::shared_ptr<const Effect> effect) const;  // replaces the same kind, or adds
  Plant without(std::string_view kind) const;
  std::string to_yaml(std::string_view header_comment = "") const;

 private:
  // Runs every effect's settle once; returns the noise-free p_meas.
  double settle_chain(PlantState& st, double cmd_rad, double valve_hint_rad, double t0_s, double gap_rad) const;
  double settle_impl(PlantState& st, double p_meas_pa, double theta_cmd_rad, double t0_s, double gap_rad, bool nearest) const;

  std::vector<std::shared_ptr<const Effect>> effects_;
  std::vector<std::size_t> offsets_;  // start of each effect's state slice
  // What step() needs of each effect, in chain order, gathered once: a plain pointer and the
  // state slice, so a period makes one virtual call per effect (step) and no others.
  struct Link {
    const Effect* effect;
    std::size_t offset, size;
  };
  std::vector<Link> chain_;
  std::size_t state_size_ = 0;
  std::size_t first_sensor_ = 0;  // index of the first effect after the chamber
};

}  // namespace hil::plant
