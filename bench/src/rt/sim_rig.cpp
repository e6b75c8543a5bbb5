#include "hil/bench/rt/sim_rig.hpp"

#include <stdexcept>

#include "hil/bench/rt/loop_input.hpp"

namespace hil::bench {

void SimRig::configure(const RigSetup& setup) {
  if (setup.programme == nullptr || !setup.programme->plant)
    throw std::invalid_argument("sim rig: configure needs a campaign with a plant");
  if (!(setup.period_s > 0)) throw std::invalid_argument("sim rig: the period must be > 0");
  plant_ = setup.programme->plant;
  state_ = plant_->make_state(setup.programme->seed);
  plant_->settle(state_, setup.p_initial_pa, plant::kNaN, 0.0, setup.gap_initial_rad);
  cmd_rad_ = state_.s.theta_cmd_rad;
  period_s_ = setup.period_s;
  silent_ = false;
  reads_ = stale_reads_ = fault_reads_ = 0;
  configured_ = true;
  active_ = false;
}

void SimRig::activate() {
  if (!configured_) throw std::logic_error("sim rig: activate before configure");
  active_ = true;
}

RigStatus SimRig::read(Clock::time_point, Clock::duration, RigReading& out) noexcept {
  ++reads_;
  if (!active_) {
    ++fault_reads_;
    return RigStatus::fault;
  }
  if (silent_.load(std::memory_order_relaxed)) {
    ++stale_reads_;
    return RigStatus::stale;
  }
  const plant::Signals& s = state_.s;
  out.p_meas_pa = s.p_meas_pa;
  out.theta_motor_rad = s.theta_motor_rad;
  out.theta_target_rad = cmd_rad_;
  out.theta_valve_rad = s.theta_valve_rad;
  out.p_chamber_pa = s.p_chamber_pa;
  return RigStatus::ok;
}

RigStatus SimRig::write(Clock::time_point, Clock::duration, const RigCommand& command) noexcept {
  if (!active_) return RigStatus::fault;
  const bool silent = silent_.load(std::memory_order_relaxed);
  if (!silent) cmd_rad_ = command.theta_cmd_rad;
  // The physics goes on whether or not the link answers; the gap is the truth, not a message.
  plant_->step(state_, {cmd_rad_, plant::kNaN, command.gap_rad}, period_s_);
  return silent ? RigStatus::stale : RigStatus::ok;
}

RigHealth SimRig::health() const noexcept {
  RigHealth h;
  h.connected = active_ && !silent_.load(std::memory_order_relaxed);
  h.fault = !active_;
  h.reads = reads_;
  h.stale_reads = stale_reads_;
  h.fault_reads = fault_reads_;
  if (!active_)
    h.set_last_error("sim rig: not active");
  else if (!h.connected)
    h.set_last_error("sim rig: silent (injected fault)");
  return h;
}

bool SimRig::inject(RigFault fault, bool on) noexcept {
  if (fault != RigFault::silent) return false;
  silent_.store(on, std::memory_order_relaxed);
  return true;
}

}  // namespace hil::bench
