// A compensator is a part: a touch-state observer and the compensation law that turns what it
// sees into the jump delta_b of the integral controller (controller.hpp). Each registers itself
// by name from its own file under controller/src/compensators/ (globbed, linked whole) with
// HIL_REGISTER_COMPENSATOR, declaring its parameters with units, ranges and defaults
// (hil/param_spec.hpp, the plant's effects' type). A campaign picks one per run
// (`compensator: NAME`, its parameters in a block named after it); `hilbench compensators` lists
// them. Shipped: `robust` (this project's observer), `paper` (the paper's eq. (3), (4), (7),
// (10)) and `tracking` (docs/tracking_compensator.md).
//
// The controller owns the integral law, the KI schedule, the free-volume estimate, the motor
// model and the traverse boost; a compensator owns the rest of the period's decision, over its
// own state. Its step is real-time safe: noexcept, no allocation, no locking, no I/O (its state is
// allocated once, by initial_state, at setup).
#pragma once

#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "hil/ctl/chamber_model.hpp"
#include "hil/param_spec.hpp"
#include "hil/units.hpp"

namespace hil::ctl {

// What the compensation law may do with what the observer learns: none = observe only (the
// paper's original integral controller; the gap is still estimated, for the telemetry),
// constant = jump by the known gap, adaptive = jump by the learned gap.
enum class Compensation { none, constant, adaptive };
constexpr const char* compensation_name(Compensation c) noexcept {
  return c == Compensation::none ? "none" : c == Compensation::constant ? "constant" : "adaptive";
}

// The drive as the controller designer models it; used when no encoder angle is available.
struct MotorModel {
  double time_constant_s = 0.010;
  double rate_limit_rad_s = units::deg_to_rad(60);
};

// What the controller knows at setup, the same for every compensator.
struct CompensatorSetup {
  double period_s = 1e-3;
  Compensation compensation = Compensation::adaptive;
  double gap_known_rad = 0;    // constant: sigma
  double gap_initial_rad = 0;  // adaptive: sigma_r(0)
  ChamberModel chamber;        // the designer's nominal chamber
  MotorModel motor;            // the designer's drive
};

// One period's inputs, from the integral controller.
struct CompensatorInputs {
  double cmd_step_rad;  // the integral controller's increment this step, KI*dT*dPg
  double error_pa;      // dPg = Pg_meas - Pg_ref: its sign is the command's direction
  double p_meas_pa;     // measured chamber pressure
  double motor_rad;     // motor angle: encoder, or the controller's motor model
  double tau_s;         // nominal chamber time constant now (the KI schedule's)
  double volume_m3;     // estimated free volume now
};

struct CompensatorOutputs {
  double comp_rad = 0;        // delta_b: the jump added to the command this step
  int touch = 0;              // Tf: -1 negative touch, 0 transition, +1 positive touch
  int intention = 0;          // Mf: -1, 0, +1
  double gap_est_rad = 0;     // the gap the law uses (sigma or sigma_r; observe-only with none)
  bool gap_measured = false;  // a gap measurement completed this step
  // The motion intention flipped: the controller's traverse boost restarts at
  // traverse_boost x comp_rad (0 without a jump) and is taken back as the motor arrives.
  bool reversed = false;
};

// A compensator's state between periods. Copyable through clone() (at setup: a controller state
// is copied whole, never in the period).
class CompensatorState {
 public:
  virtual ~CompensatorState() = default;
  virtual std::unique_ptr<CompensatorState> clone() const = 0;
};

class Compensator {
 public:
  virtual ~Compensator() = default;
  virtual std::string_view name() const noexcept = 0;
  // touch: the flank the motor is believed to rest on at start (0 = unknown). Setup time.
  virtual std::unique_ptr<CompensatorState> initial_state(double theta_cmd_rad, double p_meas_pa, int touch) const = 0;
  // One period. Real-time safe: noexcept, no allocation, no locking, no I/O. `out` arrives
  // value-initialised.
  virtual void step(CompensatorState& state, const CompensatorInputs& in, CompensatorOutputs& out) const noexcept = 0;
};

// Convenience base: Derived has `State` (a plain struct), `State initial(theta_cmd_rad,
// p_meas_pa, touch) const` and `void step(State&, const CompensatorInputs&, CompensatorOutputs&)
// const noexcept`; this wraps the state and casts it back in the period (no virtual call but the
// one into the compensator).
template <class Derived, class State>
class CompensatorOf : public Compensator {
  struct Box final : CompensatorState {
    State s;
    explicit Box(const State& state) : s(state) {}
    std::unique_ptr<CompensatorState> clone() const override { return std::make_unique<Box>(s); }
  };

 public:
  std::string_view name() const noexcept override { return Derived::kName; }
  std::unique_ptr<CompensatorState> initial_state(double theta_cmd_rad, double p_meas_pa, int touch) const override {
    return std::make_unique<Box>(static_cast<const Derived&>(*this).initial(theta_cmd_rad, p_meas_pa, touch));
  }
  void step(CompensatorState& state, const CompensatorInputs& in, CompensatorOutputs& out) const noexcept override {
    static_cast<const Derived&>(*this).step(static_cast<Box&>(state).s, in, out);
  }
};

struct CompensatorInfo {
  std::string_view name;
  std::span<const ParamSpec> specs;  // in config units, in the order make() reads them
  // values: one per spec, checked against the specs. Throws std::invalid_argument.
  std::shared_ptr<const Compensator> (*make)(const CompensatorSetup& setup, std::span<const double> values);
  std::string_view doc;
};

bool register_compensator(const CompensatorInfo& info);
const CompensatorInfo* find_compensator(std::string_view name);
std::vector<std::string> compensator_names();
// The named compensator with `values` (empty: every default), checked; throws
// std::invalid_argument naming the compensator, the parameter and its range.
std::shared_ptr<const Compensator> make_compensator(std::string_view name, const CompensatorSetup& setup,
                                                    std::span<const double> values);

}  // namespace hil::ctl

// Registers Class (kName, kSpecs, a constructor (const CompensatorSetup&, std::span<const double>)).
#define HIL_REGISTER_COMPENSATOR(Class, doc_text)                                                                              \
  namespace {                                                                                                                  \
  [[maybe_unused]] const bool registered_compensator_##Class =                                                                 \
      ::hil::ctl::register_compensator({Class::kName, Class::kSpecs,                                                           \
                                        [](const ::hil::ctl::CompensatorSetup& setup,                                          \
                                           std::span<const double> values) -> std::shared_ptr<const ::hil::ctl::Compensator> { \
                                          return std::make_shared<const Class>(setup, values);                                 \
                                        },                                                                                     \
                                        doc_text});                                                                            \
  }
