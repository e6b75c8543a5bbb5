// Fault scenarios for the CAN and Modbus rigs, run through CampaignRunner against the simulator
// side (hil_chain.hpp): on the in-process loopback bus (rig_faults_test.cpp) and on a real vcan0
// (vcan_rigs_test.cpp). In every case: the safe state in the period the loop first read a reported
// fault, or after exactly watchdog_misses missed reads for a silent device, a trip event naming
// the cause, every telemetry row up to the fault (and through the safe hold) on disk and parsing,
// and the bench usable afterwards. Counted in loop periods, so it holds on a loaded machine.
#pragma once

#include <functional>

#include "hil_chain.hpp"
#include "lockstep.hpp"

namespace hil::test {

struct FaultSetup {
  drv::CanTransportFactory can_transport;  // empty: SocketCAN
  std::string can_interface = "vcan0";
  double period_ms = 1;  // the campaign's dT
};

// The checks every fault run passes. `expect_trip`: run.json trip reason; the run's reason and
// the trip event's detail contain `text`. `watchdog`: the rig's watchdog_misses.
//
// What is checked holds on a loaded machine, because it is counted in loop periods, not time:
// a reported device fault trips the loop in the very period that first reads it; a silent
// device trips the watchdog after exactly `watchdog` missed reads in a row.
inline void expect_safe_stop(const RunFiles& f, const std::string& expect_trip, const std::string& text, double period_s,
                             int watchdog) {
  EXPECT_EQ(f.run["outcome"], "aborted") << f.run.dump(2);
  EXPECT_EQ(f.run["trip"]["reason"], expect_trip) << f.run.dump(2);
  const std::string why = expect_trip == "rig fault" ? text : "watchdog: " + std::to_string(watchdog) + " rig reads missed";
  EXPECT_NE(f.run["reason"].get<std::string>().find(why), std::string::npos) << f.run["reason"];
  // The reason names the cause for the watchdog too (it gave only the count of missed reads).
  EXPECT_NE(f.run["reason"].get<std::string>().find(text), std::string::npos) << f.run["reason"];
  const json* trip = f.event("trip");
  const json* safe = f.event("safe_state");
  ASSERT_TRUE(trip && safe);
  EXPECT_EQ((*trip)["reason"], expect_trip);
  EXPECT_NE(trip->value("detail", "").find(text), std::string::npos) << trip->dump();
  EXPECT_EQ((*safe)["period"], (*trip)["period"]);

  // Every row parsed (RunFiles reads strictly); none missing; none lost.
  EXPECT_EQ(f.run["telemetry"]["rows_lost"], 0);
  ASSERT_EQ(f.csv.rows(), f.run["telemetry"]["rows_written"].get<std::size_t>());
  ASSERT_EQ(f.csv.rows(), f.run["periods_run"].get<std::size_t>());
  for (std::size_t i = 0; i < f.csv.rows(); ++i) ASSERT_NEAR(f.csv.values[0][i], i * period_s, 1e-9);

  const auto [first, safe_row] = f.fault_and_safe_rows();
  ASSERT_GE(first, 0) << "no missed reading before the safe state";
  EXPECT_EQ(safe_row, (*trip)["period"].get<long>());
  if (expect_trip == "rig fault") {
    // The safe state in the period the loop first read the device's fault.
    long first_fault = -1;
    for (std::size_t i = 0; i < f.csv.rows() && first_fault < 0; ++i) {
      if (f.flags(i) & kFlagDeviceFault) first_fault = static_cast<long>(i);
    }
    EXPECT_EQ(safe_row, first_fault) << "the loop read the fault in period " << first_fault << ", safe state in " << safe_row;
    EXPECT_TRUE(f.flags(static_cast<std::size_t>(safe_row)) & kFlagDeviceFault);
    std::printf("%s: the loop read the fault and entered the safe state in period %ld; trip detail: %s\n", expect_trip.c_str(),
                safe_row, trip->value("detail", "").c_str());
  } else {
    // Exactly `watchdog` missed reads in a row, the last one the trip.
    EXPECT_EQ(safe_row - first + 1, watchdog) << "missed reads in a row before the safe state";
    std::printf("%s: %ld missed reads in a row from period %ld, safe state in period %ld; trip detail: %s\n", expect_trip.c_str(),
                safe_row - first + 1, first, safe_row, trip->value("detail", "").c_str());
  }
  // Held from then on (safe_state: hold), up to the end of the safe hold.
  const double held = f.csv.values[2][static_cast<std::size_t>(safe_row)];
  for (std::size_t i = static_cast<std::size_t>(safe_row); i < f.csv.rows(); ++i) {
    ASSERT_TRUE(f.flags(i) & kFlagSafeState) << "row " << i;
    ASSERT_EQ(f.csv.values[2][i], held) << "row " << i;
  }
  EXPECT_GT(f.csv.rows() - static_cast<std::size_t>(safe_row), 10u) << "the safe hold is not on disk";
}

// Rows after `row` whose reading was fresh again (the device answered, the link came back).
inline long fresh_rows_after(const RunFiles& f, long row) {
  long n = 0;
  for (std::size_t i = static_cast<std::size_t>(row) + 1; i < f.csv.rows(); ++i) n += !(f.flags(i) & kFlagReadMissed);
  return n;
}

// When a scenario's fault is injected: once the loop is 0.1 s in (the test thread watches the
// status), or before the run starts (a fault whose effect must precede a given loop time: on a
// busy machine, above all in the TCG VM where the SCHED_FIFO loop can starve the test's thread,
// "0.1 s in" was seen by the test only seconds of loop time later).
enum class InjectAt { loop_0_1_s, before_start };

// Runs a 4 s campaign on `rig_text`, calls `inject` as `at` says, waits for the end.
// A run that tripped before the injection, or for another reason, is retried (5 tries, reported):
// a stall of the machine longer than the watchdog (see kSilentDriveWatchdog) is not the fault under test.
inline RunFiles run_with_fault(Bench& b, const bench::Campaign& c, const std::string& rig_text, const std::string& expect_trip,
                               const std::function<void()>& inject, const std::function<void()>& undo,
                               InjectAt at = InjectAt::loop_0_1_s, const std::vector<std::string>& runs = {"adaptive"}) {
  for (int attempt = 1;; ++attempt) {
    if (at == InjectAt::before_start) inject();
    b.start(c, rig_text, runs);
    const bool reached = at == InjectAt::before_start || b.wait_t(0.1, std::chrono::seconds(60));
    const double t_inject =
        at == InjectAt::before_start ? 0.0 : b.runner().status().value("progress", json::object()).value("t_s", 0.0);
    if (reached && at == InjectAt::loop_0_1_s) inject();
    const json last = b.finish(std::chrono::seconds(60));
    undo();
    RunFiles f(b.runs().back());
    // (status shows the time after the period in progress: allow one period and rounding.)
    const bool spurious = !reached || f.run["trip"].is_null() || f.run["trip"]["reason"] != expect_trip ||
                          f.run["trip"]["t_s"].get<double>() < t_inject - 1.5 * c.period_s;
    if (!spurious || attempt == 5) return f;
    std::printf("retrying: attempt %d ended '%s' (%s) before or apart from the injected fault at t = %.3f s\n", attempt,
                last.value("outcome", "").c_str(), last["reason"].is_string() ? last["reason"].get<std::string>().c_str() : "",
                t_inject);
    {  // What the loop saw, for whoever reads the log of a retry.
      std::size_t fresh = 0;
      double motor_min = 1e9, motor_max = -1e9, cmd_min = 1e9, cmd_max = -1e9;
      for (std::size_t i = 0; i < f.csv.rows(); ++i) {
        if (f.flags(i) & kFlagReadMissed) continue;
        ++fresh;
        motor_min = std::min(motor_min, f.csv.values[3][i]), motor_max = std::max(motor_max, f.csv.values[3][i]);
        cmd_min = std::min(cmd_min, f.csv.values[2][i]), cmd_max = std::max(cmd_max, f.csv.values[2][i]);
      }
      std::printf("  rows %zu, fresh readings %zu; motor %.3f..%.3f deg, command %.3f..%.3f deg; loop %s\n", f.csv.rows(), fresh,
                  motor_min, motor_max, cmd_min, cmd_max, f.run.value("loop", json::object()).dump().substr(0, 400).c_str());
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
}

// After a fault the same bench runs the next campaign to completion (the rig file with the
// default watchdog of hil_chain.hpp and relaxed client timeouts: this checks that the devices
// work again, not the watchdog or the timeouts, which a busy machine can exceed).
// `campaign`, `runs`: another campaign than the 1 s paper one.
inline void expect_next_campaign_completes(Bench& b, const FaultSetup& s, const std::string& rig_text,
                                           const bench::Campaign* campaign = nullptr,
                                           const std::vector<std::string>& runs = {"adaptive"}) {
  for (int attempt = 1; attempt <= 3; ++attempt) {
    b.start(campaign != nullptr ? *campaign : short_paper_campaign(1.0, 0, s.period_ms), rig_text, runs);
    const json last = b.finish(std::chrono::seconds(60));
    if (last["outcome"] == "completed") return;
    std::printf("after the fault, attempt %d ended '%s': %s\n", attempt, last.value("outcome", "").c_str(), last.dump().c_str());
  }
  ADD_FAILURE() << "the bench did not run a campaign to completion after the fault";
}

// The watchdog of the fault runs where a silent device is the subject: it must trip before the
// device's own timeout reports the silence as a fault (the drive's heartbeat timeout, raised to
// 5 s for that run; the Modbus client's 100 ms response timeout), and a machine under load should
// not stall that many periods by itself (the VM here: wake-ups up to 90 ms late at load 7; a run
// that trips before the injection is retried). Where a reported fault is the subject the watchdog
// is out of the way (RigOptions' default).
inline constexpr int kSilentDriveWatchdog = 100, kSilentTransducerWatchdog = 40;
inline RigOptions fault_rig(int safe_hold_ms = 200, int watchdog = RigOptions{}.watchdog_misses) {
  RigOptions o;
  o.watchdog_misses = watchdog;
  o.safe_hold_ms = safe_hold_ms;
  return o;
}

// The drive stops its heartbeat (TPDOs still flow): the client declares it lost after its timeout
// (100 ms here) and reports a fault; the loop trips on the first period that reads it. The
// heartbeat comes back during the safe hold: the run's record still names the lost heartbeat as
// the cause (issue 38 item 9: it used to end as a drive that "switched itself off").
inline void heartbeat_loss(const FaultSetup& s) {
  const auto c = short_paper_campaign(4, 0, s.period_ms);
  SimulatorSide side(c, s.can_transport, s.can_interface);
  Bench b(s.can_transport);
  const std::string rig = can_rig_yaml(side, fault_rig(1000), s.can_interface, "recover", {.heartbeat_ms = 100});
  const RunFiles f = run_with_fault(
      b, c, rig, "rig fault",
      [&] {
        side.can.stop_heartbeat(true);
        wait_state([&] { return b.runner().status().value("state", "") == "safe"; }, std::chrono::seconds(60));
        side.can.stop_heartbeat(false);  // back while the safe state holds
      },
      [&] { side.can.stop_heartbeat(false); });
  expect_safe_stop(f, "rig fault", "heartbeat lost", c.period_s, RigOptions{}.watchdog_misses);
  EXPECT_NE(f.run["reason"].get<std::string>().find("CiA 402 drive node 5"), std::string::npos) << f.run["reason"];
  // How the rig ended the run (after the heartbeat came back): the cause, kept.
  EXPECT_TRUE(f.run["rig_health"]["fault"].get<bool>()) << f.run["rig_health"];
  EXPECT_NE(f.run["rig_health"]["last_error"].get<std::string>().find("heartbeat lost (none for 100 ms)"), std::string::npos)
      << f.run["rig_health"];
  expect_next_campaign_completes(b, s, can_rig_yaml(side, {}, s.can_interface, "recover", kRelaxedTimeouts));
}

// The drive falls silent (no TPDO, no heartbeat): stale from the first SYNC unanswered, the
// watchdog trips on the kSilentDriveWatchdog-th (before the 5 s heartbeat timeout would).
inline void drive_silent(const FaultSetup& s) {
  const auto c = short_paper_campaign(4, 0, s.period_ms);
  SimulatorSide side(c, s.can_transport, s.can_interface);
  Bench b(s.can_transport);
  const std::string rig =
      rig_yaml("can", can_drive_yaml(s.can_interface, "recover", 5000),
               modbus_device_yaml(side.transducer.port(), "modbus_transducer_map.yaml"), fault_rig(200, kSilentDriveWatchdog));
  const RunFiles f = run_with_fault(
      b, c, rig, "watchdog", [&] { side.can.set_silent(true); }, [&] { side.can.set_silent(false); });
  expect_safe_stop(f, "watchdog", "drive: no TPDO since the last SYNC", c.period_s, kSilentDriveWatchdog);
}

// An EMCY puts the drive in fault: the trip names the EMCY decoded (class, error register,
// manufacturer bytes), not just its code: a following error, as a drive reports one.
inline void emcy_fault(const FaultSetup& s) {
  const auto c = short_paper_campaign(4, 0, s.period_ms);
  SimulatorSide side(c, s.can_transport, s.can_interface);
  Bench b(s.can_transport);
  const std::string rig = can_rig_yaml(side, fault_rig(), s.can_interface);
  const RunFiles f = run_with_fault(
      b, c, rig, "rig fault",
      [&] {
        side.can.raise_emcy(0x8611, 0x20, {0x10, 0x27, 0x00, 0x00, 0x00});
      },
      [] {});
  expect_safe_stop(f, "rig fault", "drive: CiA 402 drive node 5", c.period_s, RigOptions{}.watchdog_misses);
  const std::string reason = f.run["reason"].get<std::string>();
  EXPECT_NE(reason.find("drive entered fault: EMCY 0x8611 (following error), register 0x21 (generic, device profile), "
                        "manufacturer 10 27 00 00 00"),
            std::string::npos)
      << reason;
  expect_next_campaign_completes(
      b, s, can_rig_yaml(side, {}, s.can_interface, "recover", kRelaxedTimeouts));  // activate() resets the fault
}

// Bus-off: detected (the client latches it from the error frame), reported (trip detail),
// recovered (policy recover: the channel reopens after 200 ms, readings come back within the safe
// hold, and the next campaign completes).
inline void bus_off(const FaultSetup& s) {
  const auto c = short_paper_campaign(4, 0, s.period_ms);
  SimulatorSide side(c, s.can_transport, s.can_interface);
  Bench b(s.can_transport);
  const std::string rig = can_rig_yaml(side, fault_rig(1500), s.can_interface, "recover");
  const RunFiles f = run_with_fault(
      b, c, rig, "rig fault", [&] { side.can.emulate_bus_error(drv::EmulatedBusError::bus_off); }, [] {});
  expect_safe_stop(f, "rig fault", "bus-off", c.period_s, RigOptions{}.watchdog_misses);
  const long trip = (*f.event("trip"))["period"];
  EXPECT_GT(fresh_rows_after(f, trip), 10) << "no fresh reading after the bus-off recovery within the safe hold";
  // The drive recovered once. The Modbus transducer may add a reconnect of its own when a loaded
  // machine delays one of its replies past the response timeout; that is counted apart.
  EXPECT_EQ(f.run["rig_health"]["reconnects_by_device"]["drive"], 1) << f.run["rig_health"];
  EXPECT_EQ(f.run["rig_health"]["reconnects"], f.run["rig_health"]["reconnects_by_device"]["drive"].get<int>() +
                                                   f.run["rig_health"]["reconnects_by_device"]["transducer"].get<int>());
  expect_next_campaign_completes(b, s, can_rig_yaml(side, {}, s.can_interface, "recover", kRelaxedTimeouts));
}

// An operator's abort while the rig is being set up: the drive answers nothing, so configure()
// waits for its boot-up up to boot_ms (600 s here). The abort used to wait that out; now it cuts
// the setup short and the run ends "aborted", naming the setup it cut.
inline void abort_during_setup(const FaultSetup& s) {
  const auto c = short_paper_campaign(4, 0, s.period_ms);
  SimulatorSide side(c, s.can_transport, s.can_interface);
  Bench b(s.can_transport);
  std::string rig = can_rig_yaml(side, fault_rig(), s.can_interface);
  const std::string boot = "boot_ms: 10000";
  ASSERT_NE(rig.find(boot), std::string::npos);
  rig.replace(rig.find(boot), boot.size(), "boot_ms: 600000");
  side.can.set_silent(true);
  b.start(c, rig);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // configure() is waiting by now
  b.runner().abort("operator abort: at once");                  // as the server words it
  const json last = b.finish(std::chrono::seconds(10));         // not 600 s
  EXPECT_EQ(last["outcome"], "aborted") << last.dump();
  const std::string reason = last.value("reason", "");
  EXPECT_NE(reason.find("operator abort: at once during the setup of rig 'test_rig_1' (CiA 402 drive node 5 on " +
                        s.can_interface + ": configure() cancelled)"),
            std::string::npos)
      << reason;
  side.can.set_silent(false);
  expect_next_campaign_completes(b, s, can_rig_yaml(side, {}, s.can_interface, "recover", kRelaxedTimeouts));
}

// An SDO abort while the rig configures the drive: the run ends in error with a message naming
// the object; nothing ran, the telemetry file holds its header; once the drive stops refusing,
// the next campaign completes.
inline void sdo_abort(const FaultSetup& s) {
  const auto c = short_paper_campaign(4, 0, s.period_ms);
  SimulatorSide side(c, s.can_transport, s.can_interface);
  Bench b(s.can_transport);
  const std::string rig = can_rig_yaml(side, fault_rig(), s.can_interface);
  side.can.fail_sdo(0x6060, 0, 0x08000022);
  b.start(c, rig);
  const json last = b.finish(std::chrono::seconds(60));
  EXPECT_EQ(last["outcome"], "error");
  const RunFiles f(b.runs().back());
  EXPECT_EQ(f.run["outcome"], "error");
  const std::string reason = f.run["reason"];
  EXPECT_NE(reason.find("rig 'test_rig_1' setup: CiA 402 drive node 5 on " + s.can_interface +
                        ": SDO write 0x6060:00: abort 0x08000022"),
            std::string::npos)
      << reason;
  EXPECT_NE(reason.find("present device state"), std::string::npos) << reason;
  const json* err = f.event("rig_error");
  ASSERT_NE(err, nullptr);
  EXPECT_EQ((*err)["detail"], reason);
  EXPECT_EQ(f.csv.rows(), 0u);  // the header is on disk and parses
  side.can.clear_sdo_failures();
  expect_next_campaign_completes(b, s, can_rig_yaml(side, {}, s.can_interface, "recover", kRelaxedTimeouts));
}

// Modbus timeout (modbus rig): the transducer stops answering; its reading ages past two polls,
// the watchdog trips after 3 stale periods. When it answers again the client, which closed the
// connection on the timeout, reconnects and the readings resume within the safe hold; the next
// campaign completes.
inline void modbus_timeout(const FaultSetup& s) {
  const auto c = short_paper_campaign(4, 0, s.period_ms);
  SimulatorSide side(c, s.can_transport, s.can_interface);
  Bench b(s.can_transport);
  const std::string rig = modbus_rig_yaml(side, fault_rig(1500, kSilentTransducerWatchdog));
  const RunFiles f = run_with_fault(
      b, c, rig, "watchdog",
      [&] {
        side.transducer.set_silent(true);
        // Silent until the loop is in the safe state, then answer again (the client times out,
        // reconnects and reads) while the safe state holds.
        wait_state([&] { return b.runner().status().value("state", "") == "safe"; }, std::chrono::seconds(60));
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        side.transducer.set_silent(false);
      },
      [&] { side.transducer.set_silent(false); });
  expect_safe_stop(f, "watchdog", "transducer: newest reading", c.period_s, kSilentTransducerWatchdog);
  const long trip = (*f.event("trip"))["period"];
  EXPECT_GT(fresh_rows_after(f, trip), 10) << "the readings did not resume after the reconnect";
  EXPECT_GE(f.run["rig_health"]["reconnects_by_device"]["transducer"].get<int>(), 1)
      << f.run["rig_health"];  // closed on the timeout, reopened
  EXPECT_TRUE(f.run["rig_health"]["connected"].get<bool>()) << f.run["rig_health"];
  expect_next_campaign_completes(b, s, modbus_rig_yaml(side, {}, kRelaxedTimeouts));
}

// A Modbus transducer answering every read with an exception reply (ILLEGAL DATA ADDRESS): no
// reading arrives, the watchdog trips after kSilentTransducerWatchdog stale periods, and the run's
// reason and the trip's detail name the exception. They said "watchdog: 40 rig reads missed in a
// row" and nothing of why; the client knew (its last error) but the rig's stale text dropped it.
inline void modbus_read_exception(const FaultSetup& s) {
  const auto c = short_paper_campaign(4, 0, s.period_ms);
  SimulatorSide side(c, s.can_transport, s.can_interface);
  Bench b(s.can_transport);
  const std::string rig = modbus_rig_yaml(side, fault_rig(200, kSilentTransducerWatchdog));
  const RunFiles f = run_with_fault(
      b, c, rig, "watchdog", [&] { side.transducer.set_exception(2); }, [&] { side.transducer.set_exception(0); });
  expect_safe_stop(f, "watchdog", "ILLEGAL DATA ADDRESS (exception 2)", c.period_s, kSilentTransducerWatchdog);
  EXPECT_NE(f.run["reason"].get<std::string>().find("transducer: newest reading"), std::string::npos) << f.run["reason"];
}

// A frozen encoder: the drive reports the position it had while the motor moves on. Nothing
// the drive or the link reports, and readings keep arriving: no other interlock sees it. The
// following error does. The encoder is frozen before the run starts (it reports its first
// position throughout); the reference steps 1.0 -> 1.8 MPa at 0.5 s and the command moves about
// 9 deg to follow it, the reported position stays, and the loop trips after exactly time_ms / dT
// readings in a row with the position beyond max_deg from the target sent the period before,
// counted in the telemetry (so it holds on a loaded machine). With the same limit a run without
// the fault completes.
// Made to hold in the TCG VM beside a sanitizer build, where it completed in every retry: there
// 78 % of the readings came late (missed: the controller holds, so the command moved 2.5 deg in
// the 1.5 s after a step at 2.5 s, within a hair of the 2 deg limit), the freeze "0.1 s in" came
// when the test's thread got to run, and the adaptive compensation, whose observer reads the frozen
// encoder, moved the command 2 deg before the step once. Now: no compensation (this is the
// interlock's test, not the observer's), the freeze before the start, and a larger, earlier step
// (3.5 s to move the command 9 deg past a 2 deg limit; before the step it moves only with noise).
inline bench::Campaign frozen_encoder_campaign(double period_ms) {
  return bench::load_campaign_text(
      "name: frozen_encoder\n"
      "plant: ../plant/nominal.yaml\n"
      "duration_s: 4\n"
      "period_ms: " +
          std::to_string(period_ms) +
          "\n"
          "seed: 1\n"
          "sensor_noise_kpa: 2.0\n"
          "reference:\n"
          "  initial_mpa: 1.0\n"
          "  profile:\n"
          "    - step: {at_s: 0.5, to_mpa: 1.8}\n"
          "gap:\n"
          "  initial_deg: 1.0\n"
          "runs:\n"
          "  - name: uncompensated\n"
          "    compensation: none\n",
      "frozen_encoder (test)", source_path("configs/campaigns"));
}

inline void frozen_encoder(const FaultSetup& s, bool modbus_drive) {
  const auto c = frozen_encoder_campaign(s.period_ms);
  constexpr double kStepS = 0.5;
  SimulatorSide side(c, s.can_transport, s.can_interface);
  Bench b(s.can_transport);
  constexpr double kMaxDeg = 2;
  constexpr int kTimeMs = 50;
  RigOptions o = fault_rig();
  o.loop_extra = "target_shaping: {max_velocity_deg_s: 60, max_acceleration_deg_s2: 30000}";  // as the shipped rigs
  o.safety_extra = "following_error: {max_deg: 2, time_ms: 50}";
  const std::string rig = modbus_drive ? modbus_rig_yaml(side, o) : can_rig_yaml(side, o, s.can_interface);
  const auto freeze = [&](bool on) { modbus_drive ? side.drive.freeze_position(on) : side.can.freeze_position(on); };
  const RunFiles f = run_with_fault(
      b, c, rig, "following error", [&] { freeze(true); }, [&] { freeze(false); }, InjectAt::before_start, {"uncompensated"});
  EXPECT_EQ(f.run["outcome"], "aborted") << f.run.dump(2);
  ASSERT_EQ(f.run["trip"]["reason"], "following error") << f.run.dump(2);
  const std::string reason = f.run["reason"];
  EXPECT_NE(reason.find("following error: the drive's position"), std::string::npos) << reason;
  EXPECT_NE(reason.find("beyond the 2.000 deg limit for 50 ms in a row"), std::string::npos) << reason;
  const json* trip = f.event("trip");
  ASSERT_NE(trip, nullptr);
  EXPECT_EQ((*trip)["limit_deg"], kMaxDeg);
  EXPECT_GT(std::abs((*trip)["error_deg"].get<double>()), kMaxDeg) << trip->dump();
  EXPECT_GT((*trip)["t_s"].get<double>(), kStepS) << "tripped before the reference step moved the command";

  // The periods before the trip, from the telemetry: the last kTimeMs readings (missed ones do
  // not count) beyond the limit, the one before them within it, and the reported position frozen.
  CsvHeader header;
  const CsvChunk t =
      read_csv(f.dir / "telemetry.csv", {{"t_s", "theta_target_deg", "theta_motor_deg", "loop_flags"}, {}, "t_s"}, &header);
  const long trip_row = (*trip)["period"].get<long>();
  ASSERT_GT(trip_row, kTimeMs + 1);
  const auto error_deg = [&](long k) {
    return t.values[2][static_cast<std::size_t>(k)] - t.values[1][static_cast<std::size_t>(k - 1)];
  };
  const auto missed = [&](long k) {
    return (static_cast<std::uint32_t>(t.values[3][static_cast<std::size_t>(k)]) & kFlagReadMissed) != 0;
  };
  constexpr double kRoundingDeg = 1e-4;  // the file's decimals
  const int periods = static_cast<int>(std::lround(kTimeMs / s.period_ms));
  long k = trip_row;
  for (int n = 0; n < periods; --k) {
    ASSERT_GT(k, 1);
    if (missed(k)) continue;
    EXPECT_GT(std::abs(error_deg(k)), kMaxDeg - kRoundingDeg) << "row " << k;
    EXPECT_EQ(t.values[2][static_cast<std::size_t>(k)], t.values[2][static_cast<std::size_t>(trip_row)]) << "row " << k;
    ++n;
  }
  while (k > 1 && missed(k)) --k;
  EXPECT_LT(std::abs(error_deg(k)), kMaxDeg + kRoundingDeg) << "row " << k << ": more than " << periods << " periods beyond";
  std::printf("following error: %.3f deg at the trip in period %ld, %d readings beyond %.1f deg before it\n",
              (*trip)["error_deg"].get<double>(), trip_row, periods, kMaxDeg);
  // The same campaign and limit without the fault: completes (the limit is not one that the step
  // itself, shaped and followed with the drive's lag, would trip).
  RigOptions same = {};
  same.loop_extra = o.loop_extra;
  same.safety_extra = o.safety_extra;
  expect_next_campaign_completes(b, s,
                                 modbus_drive ? modbus_rig_yaml(side, same, kRelaxedTimeouts)
                                              : can_rig_yaml(side, same, s.can_interface, "recover", kRelaxedTimeouts),
                                 &c, {"uncompensated"});
}

}  // namespace hil::test
