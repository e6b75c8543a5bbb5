// The simulated rig: the campaign's plant stepped in lock-step with the loop (one plant step of
// the campaign's dT per write, whatever the wall-clock pacing). It can stop answering on purpose
// (RigFault::silent) so the watchdog can be tested against the real loop.
#pragma once

#include <atomic>
#include <memory>

#include "hil/bench/rt/rig.hpp"
#include "hil/plant/plant.hpp"

namespace hil::bench {

class SimRig final : public Rig {
 public:
  SimRig() = default;

  std::string_view kind() const noexcept override { return "sim"; }
  bool simulated() const noexcept override { return true; }
  bool programmable_gap() const noexcept override { return true; }
  bool knows_truth() const noexcept override { return true; }

  // Builds the plant state from the campaign's seed and settles it at the reference and gap of t = 0.
  void configure(const RigSetup& setup) override;
  void activate() override;
  void deactivate() noexcept override { active_ = false; }

  // Real-time safe.
  RigStatus read(Clock::time_point now, Clock::duration period, RigReading& out) noexcept override;
  // Real-time safe: steps the plant one dT with this command (the last one received while silent).
  RigStatus write(Clock::time_point now, Clock::duration period, const RigCommand& command) noexcept override;
  RigHealth health() const noexcept override;
  bool inject(RigFault fault, bool on) noexcept override;

 private:
  std::shared_ptr<const plant::Plant> plant_;
  plant::PlantState state_;
  double period_s_ = 1e-3;
  double cmd_rad_ = 0;
  bool configured_ = false, active_ = false;
  std::atomic<bool> silent_{false};
  std::uint64_t reads_ = 0, stale_reads_ = 0, fault_reads_ = 0;
};

}  // namespace hil::bench
