// One run's session on a rig, as ros2_control's resource manager has a hardware component's
// lifecycle: configure and activate the rig, set the loop up (RunLoop), run it on its own
// real-time thread to its end, deactivate the rig, finish the recorder, and say how the run
// ended (the outcome and its reason, in the operator's words) and what run.json keeps of it.
// Whoever owns the run (the campaign runner of `hilbench serve` and `hilbench run`) keeps the
// sequencing, the operator's requests and the status; it hears the session through the hooks.
// Not real-time: this is the thread that sets the loop up and waits for it.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "hil/bench/rt/loop_input.hpp"
#include "hil/bench/rt/recorder.hpp"
#include "hil/bench/rt/rig_config.hpp"
#include "hil/bench/rt/rt_loop.hpp"
#include "hil/bench/rt/rt_thread.hpp"
#include "hil/bench/rt/run_record.hpp"

namespace hil::bench {

// How a session talks to the run's owner, on the session's thread; each may be empty.
struct RunSessionHooks {
  // The rig whose configure() and activate() run now, then nullptr: an abort in between cancels
  // them (Rig::cancel_setup).
  std::function<void(Rig*)> in_setup;
  // The abort asked of the run, if any: the reason it ends with. Asked when the setup failed and
  // when the loop ended on an operator abort.
  std::function<std::optional<std::string>()> abort_reason;
  // The loop is set up and about to run its first period: the owner's handle for status and
  // requests (a stop or an abort asked before goes in now). The loop waits for the return.
  std::function<void(const RunLoop&, SpscRing<LoopRequest>&, const RtSetup&)> loop_ready;
};

class RunSession {
 public:
  // All must outlive the session. `speed`: loop periods per control period of wall time.
  // `mlock_warning`: what lock_memory() said ("" = memory locked), for the record.
  RunSession(Rig& rig, const RigConfig& rig_config, const LoopProgramme& programme, const RunSpec& run, double speed,
             Recorder& recorder, std::string mlock_warning);
  RunSession(const RunSession&) = delete;
  RunSession& operator=(const RunSession&) = delete;
  ~RunSession();

  // The whole session; a rig that cannot be set up, a trip or a recording fault is its outcome,
  // never an exception. Logs rig_error, loop_start and drive_not_disabled events on the way.
  void run(const RunSessionHooks& hooks);

  Outcome outcome() const noexcept { return outcome_; }
  const std::string& reason() const noexcept { return reason_; }
  const RunLoop* loop() const noexcept { return loop_.get(); }  // null: the run never reached its loop
  // The end of the run's record: outcome, reason, the rig's health, the trip, the periods run,
  // the loop's statistics and the telemetry's counts (the caller adds stop_utc and the checks).
  void record_end(RunRecord& record) const;

 private:
  bool set_up(const RunSessionHooks& hooks);
  void run_loop(const RunSessionHooks& hooks);
  void deactivate();

  Rig& rig_;
  const RigConfig& rc_;
  const LoopProgramme& programme_;
  const RunSpec& run_;
  const double speed_;
  Recorder& rec_;
  const std::string mlock_warning_;
  SpscRing<LoopRequest> requests_;
  std::unique_ptr<RunLoop> loop_;
  RtSetup rt_;
  Outcome outcome_ = Outcome::error;
  std::string reason_, write_error_;
  nlohmann::json rig_health_;  // how the rig's devices ended the run (null: the loop never ran)
};

// The loop's timing statistics (periods, overruns, latency and compute summaries, rig call
// times): in run.json's `loop` and the status.
nlohmann::json loop_stats_json(const RunLoop& loop);

}  // namespace hil::bench
