// A physical effect: one small, const piece of the plant (motor servo, backlash, throat map,
// gas generator, sensor, and the candidates the workbench adds). Effects are chained by Stage in
// signal-flow order; each owns a slice of the plant's flat state vector and advances it over one
// step. Adding an effect means one class here plus HIL_REGISTER_EFFECT: nothing else changes.
#pragma once

#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "hil/param_spec.hpp"
#include "hil/plant/rng.hpp"
#include "hil/plant/signals.hpp"

namespace hil::plant {

// Signal-flow order. Effects of a later stage see what earlier stages wrote into Signals.
enum class Stage : int {
  command = 0,      // what happens to the command before the drive (transport delay)
  motor,            // drive + motor: theta_cmd -> theta_motor
  gap,              // backlash size over time -> gap
  transmission,     // motor -> valve through the gap -> theta_valve (and theta_throat = theta_valve)
  valve,            // valve -> throat geometry (offsets) -> theta_throat
  throat,           // theta_throat -> throat_area
  throat_modifier,  // area changes not due to the angle (erosion)
  chamber,          // throat_area -> chamber pressure and volume; then p_meas = p_chamber
  sensor,           // transducer dynamics on p_meas (lag)
  sensor_modifier,  // static transducer errors (bias, gain)
  sensor_noise,     // random noise, last so it is never filtered
};

// Parameter specs, their YAML reader and checker: one type for every registered part.
using ::hil::check_params;
using ::hil::ParamSpec;
using ::hil::read_params;

struct Param {
  std::string key;
  double value;
};

// A list-valued parameter (a map's breakpoints), written as a YAML flow sequence.
struct Table {
  std::string key;
  std::vector<double> values;
};

class Effect {
 public:
  virtual ~Effect() = default;
  virtual std::string_view kind() const noexcept = 0;
  virtual Stage stage() const noexcept = 0;
  virtual std::size_t state_size() const noexcept { return 0; }

  // Steady state for the upstream signals already in `s`: set own state, write own outputs.
  // Setup time only (may be slow, may throw).
  virtual void settle(std::span<double> x, Signals& s) const = 0;
  // Advance own state over one step of dt_s with inputs held. Real-time safe: noexcept,
  // no allocation, no locking, no I/O.
  virtual void step(std::span<double> x, Signals& s, double dt_s, Rng& rng) const noexcept = 0;

  // Scalar parameters in config units, for fitting and for writing the model back to YAML.
  virtual std::vector<Param> params() const = 0;
  virtual std::span<const ParamSpec> specs() const noexcept = 0;
  // A copy with new parameter values (same order as params()); throws std::invalid_argument
  // for values outside the specs.
  virtual std::shared_ptr<const Effect> with_params(std::span<const double> values) const = 0;
  // List-valued parameters (tables); default none.
  virtual std::vector<Table> tables() const { return {}; }
};

// Convenience base for effects whose parameters are all scalars: stores values, implements
// params(), specs(), with_params(). Derived(std::vector<double>) must be a constructor.
template <class Derived>
class ScalarEffect : public Effect {
 public:
  explicit ScalarEffect(std::vector<double> values) : values_(std::move(values)) {
    check_params(Derived::kKind, Derived::kSpecs, values_);
  }
  std::string_view kind() const noexcept override { return Derived::kKind; }
  Stage stage() const noexcept override { return Derived::kStage; }
  std::span<const ParamSpec> specs() const noexcept override { return Derived::kSpecs; }
  std::vector<Param> params() const override {
    std::vector<Param> out;
    for (std::size_t i = 0; i < values_.size(); ++i) out.push_back({std::string(Derived::kSpecs[i].key), values_[i]});
    return out;
  }
  std::shared_ptr<const Effect> with_params(std::span<const double> values) const override {
    return std::make_shared<Derived>(std::vector<double>(values.begin(), values.end()));
  }
  static std::shared_ptr<const Effect> from_yaml(const cfg::Node& block) {
    return std::make_shared<Derived>(read_params(block, Derived::kSpecs));
  }

 protected:
  double value(std::size_t i) const { return values_[i]; }

 private:
  std::vector<double> values_;
};

}  // namespace hil::plant
