// The rig chain in simulated time: the bench's loop (RunLoop::cycle, clock-free) and the simulator
// side step in lock-step, so a trace through the real clients, the CAN bus (loopback or vcan0),
// the CiA 402 emulator, the Modbus transducer over TCP and the plant is the same whatever the
// machine is doing. Nothing waits for a time: every wait is for a state (the drive has the
// command, the plant stepped, the rig reads the new state).
//
// Period k:  wait until the rig reads the plant's state k (TPDO with its encoder counts, newer
//            than the last SYNC; the transducer's newest reply showing its pressure)
//            -> cycle(t, t) with t = when that was seen (the rig's freshness is judged then)
//            -> wait until the emulator handed the period's target (RPDO k, applied at SYNC)
//               to the plant -> step the plant one dT with it (the campaign's gap programme
//               on the loop's clock) -> one more SYNC so the drive reports the new position.
// Real time only paces how fast this goes; 1 kHz figures stay in benchmarks (docs/benchmarks.md).
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/rt/device_rig.hpp"
#include "hil/bench/rt/rt_loop.hpp"
#include "hil/bench/campaign/sim.hpp"
#include "hil/drv/canopen.hpp"
#include "hil/drv/cia402_emulator.hpp"
#include "hil/drv/modbus_emulator.hpp"
#include "hil_chain.hpp"

namespace hil::test {

using bench::Clock;

// The rig the file's kind makes (its registered recipe, as make_rig), as the DeviceRig it is: the
// tests also look at its drive's raw feedback.
inline std::unique_ptr<bench::DeviceRig> make_device_rig(const bench::RigConfig& rc,
                                                         const drv::CanTransportFactory& can_transport = {}) {
  std::unique_ptr<bench::Rig> rig = bench::make_rig(rc, can_transport);
  if (dynamic_cast<bench::DeviceRig*>(rig.get()) == nullptr) throw std::logic_error("a " + rc.kind + " rig is no DeviceRig");
  return std::unique_ptr<bench::DeviceRig>(static_cast<bench::DeviceRig*>(rig.release()));
}

// The campaign's plant behind the CiA 402 emulator (as its drive model) and the Modbus
// transducer emulator (as its pressure model), stepped only when the harness says.
class LockstepPlant final : public drv::DriveModel, public drv::PressureModel {
 public:
  explicit LockstepPlant(const bench::Campaign& c) : plant_(c.plant), state_(plant_->make_state(c.seed)), period_s_(c.period_s) {
    plant_->settle(state_, c.reference_pa.at(0.0), plant::kNaN, 0.0, c.gap_rad.at(0.0));
  }
  // Emulator threads.
  void command(double target_rad, bool enabled) override {
    std::lock_guard lock(mutex_);
    target_rad_ = target_rad;
    enabled_ = enabled;
  }
  drv::DriveModelSample sample() override {
    std::lock_guard lock(mutex_);
    return {state_.s.theta_motor_rad, velocity_rad_s_, false, 0};
  }
  double pressure_pa() override {
    std::lock_guard lock(mutex_);
    return state_.s.p_meas_pa;
  }
  // Harness.
  std::optional<double> enabled_target() {
    std::lock_guard lock(mutex_);
    if (!enabled_) return std::nullopt;
    return target_rad_;
  }
  void step(double cmd_rad, double gap_rad) {
    std::lock_guard lock(mutex_);
    const double before = state_.s.theta_motor_rad;
    plant_->step(state_, {cmd_rad, plant::kNaN, gap_rad}, period_s_);
    velocity_rad_s_ = (state_.s.theta_motor_rad - before) / period_s_;
  }
  plant::Signals signals() {
    std::lock_guard lock(mutex_);
    return state_.s;
  }

 private:
  std::mutex mutex_;
  std::shared_ptr<const plant::Plant> plant_;
  plant::PlantState state_;
  double period_s_;
  double target_rad_ = 0, velocity_rad_s_ = 0;
  bool enabled_ = false;
};

// Waits for `pred` without a time limit that depends on machine speed: `limit` only ends a
// chain that is broken (a lost frame is answered by the next SYNC, a lost poll by the next poll).
inline bool wait_state(const std::function<bool()>& pred, std::chrono::seconds limit = std::chrono::seconds(30)) {
  const auto until = Clock::now() + limit;
  while (!pred()) {
    if (Clock::now() > until) return false;
    std::this_thread::sleep_for(std::chrono::microseconds(50));
  }
  return true;
}

struct LockstepResult {
  std::vector<bench::TelemetryRecord> rows;
  bench::LoopEnd end = bench::LoopEnd::running;
  long missed = 0;
  std::string first_miss;  // the first missed read: its period and what the rig said (a failure names the device)
  std::string error;       // a chain that broke: what it waited for
  double wall_s = 0;
};

// The simulator side of the lock-step chain on `can` (the CAN transport) and a Modbus transducer
// on an ephemeral TCP port; `sync` puts one SYNC on the bus (as a second SYNC producer would).
struct LockstepSide {
  LockstepSide(const bench::Campaign& c, const drv::CanTransportFactory& can_transport, std::function<void()> sync_fn,
               const std::string& interface = "vcan0")
      : plant(c),
        can(drv::Cia402EmulatorConfig{interface, kNode, kUnits}, plant, can_transport),
        transducer(SimulatorSide::tcp(0), drv::RegisterMap::load(source_path("drivers/configs/modbus_transducer_map.yaml")),
                   plant),
        sync(std::move(sync_fn)) {}
  LockstepPlant plant;
  drv::Cia402DriveEmulator can;
  drv::ModbusTransducerEmulator transducer;
  std::function<void()> sync;
};

// The CAN rig file for the lock-step chain: the transducer polled every 1 ms (the fastest the
// client allows) so a new pressure is seen soon; the loop's own thread settings do not matter
// (the harness is the loop thread).
// The rig file's options in lock-step: the watchdog as on a quiet real-time host (no read is ever
// missed), and no real-time scheduling (the harness is the loop thread).
inline RigOptions lockstep_rig_options() {
  RigOptions o;
  o.watchdog_misses = 3;
  o.priority = 0;
  o.cpu = -1;
  o.io_priority = 0;
  return o;
}

inline std::string lockstep_can_rig_yaml(const LockstepSide& s, const std::string& interface = "vcan0") {
  const RigOptions o = lockstep_rig_options();
  const std::string transducer =
      "    modbus: {link: {transport: tcp, host: 127.0.0.1, port: " + std::to_string(s.transducer.port()) +
      ", poll_period_ms: 1, response_timeout_ms: 1000, reconnect: {initial_ms: 20, max_ms: 200}},\n"
      "             register_map: " +
      source_path("drivers/configs/modbus_transducer_map.yaml").string() +
      "}\n"
      "    max_age_ms: 4\n";
  return rig_yaml("can", can_drive_yaml(interface), transducer, o);
}

// What a physical value becomes on the way through the wire (encoder counts, register scale).
using WireFn = std::function<double(double)>;

// Runs `run` of campaign `c` through the rig of `rig_text` (kind can or modbus) in lock-step with
// `plant` behind the rig's devices. `sync` asks a CAN drive for its newest position (no-op for
// Modbus, which polls); `wire_position`/`wire_target` say what the motor angle and the target sent
// (the command, shaped where the rig says so) become on the wire, so the harness knows when the rig shows the plant and the drive has the target.
inline LockstepResult run_lockstep_on(const bench::Campaign& c, const std::string& run, LockstepPlant& plant,
                                      const std::function<void()>& sync_fn, const std::string& rig_text,
                                      const drv::CanTransportFactory& can_transport, const WireFn& wire_position,
                                      const WireFn& wire_target) {
  LockstepResult res;
  const bench::RunSpec* spec = nullptr;
  for (const auto& r : c.runs) {
    if (r.name == run) spec = &r;
  }
  if (spec == nullptr) {
    res.error = "no run " + run;
    return res;
  }
  TempDir dir;
  const bench::RigConfig rc = bench::load_rig_config(dir.write("rigs/lockstep.yaml", rig_text));
  const auto owned_rig = make_device_rig(rc, can_transport);
  bench::DeviceRig& rig = *owned_rig;
  rig.configure({&c, c.period_s, c.reference_pa.at(0.0), c.gap_rad.at(0.0)});
  rig.activate();
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(c.period_s));
  const auto n = static_cast<std::size_t>(std::lround(c.duration_s / c.period_s));
  bench::SpscRing<bench::TelemetryRecord> telemetry(n + 16);
  bench::SpscRing<bench::LoopEvent> events(1024);
  bench::SpscRing<bench::LoopRequest> requests(16);

  // The rig shows the plant's present state: fresh (TPDO after the last SYNC, a young pressure),
  // the encoder counts of the plant's motor angle, the plant's pressure (float32 on the wire).
  Clock::time_point seen{}, synced{};
  const auto sync = [&] {
    synced = Clock::now();
    sync_fn();
  };
  const auto rig_shows_plant = [&] {
    const plant::Signals s = plant.signals();
    const double theta = wire_position(s.theta_motor_rad);
    const auto t = Clock::now();
    bench::RigReading rd;
    if (rig.read(t, period, rd) != bench::RigStatus::ok) return false;
    if (rd.theta_motor_rad != theta || !(std::abs(rd.p_meas_pa - s.p_meas_pa) <= 1e-6 * std::abs(s.p_meas_pa))) {
      // The drive answers every SYNC with its newest position: ask again if the answer to the
      // last one is not here by now (one SYNC per ms at most: this is no bus flood).
      if (t - synced > std::chrono::milliseconds(1)) sync();
      return false;
    }
    seen = t;
    return true;
  };
  const auto t0 = Clock::now();
  if (!wait_state(rig_shows_plant)) {
    res.error = "the rig never showed the settled plant: " + std::string(rig.health().last_error_text());
    rig.deactivate();
    return res;
  }
  bench::RunLoop loop(c, *spec, rig, rc.safety, rc.loop, period, telemetry, events, requests);
  loop.begin(seen);
  bench::Schedule::Cursor gap_cursor;
  for (std::size_t k = 0;; ++k) {
    if (k > 0 && !wait_state(rig_shows_plant)) {
      res.error = "period " + std::to_string(k) +
                  ": the rig did not show the plant's state: " + std::string(rig.health().last_error_text());
      break;
    }
    loop.cycle(seen, seen);
    const bool more = loop.finish_cycle(seen);
    bench::TelemetryRecord rec;
    if (telemetry.pop(&rec, 1) != 1) {
      res.error = "period " + std::to_string(k) + ": no telemetry row";
      break;
    }
    res.rows.push_back(rec);
    if ((rec.flags & bench::kFlagReadMissed) != 0 && res.missed++ == 0)
      res.first_miss = "period " + std::to_string(k) + ": " + std::string(rig.health().last_error_text());
    if (!more) break;
    // The drive has this period's target once the emulator applied RPDO k (at its SYNC).
    const double want = wire_target(rec.theta_target_rad);  // what the rig sent: the command, shaped where set
    std::optional<double> got;
    if (!wait_state([&] { return (got = plant.enabled_target()) && *got == want; })) {
      res.error = "period " + std::to_string(k) + ": the drive never got the target";
      break;
    }
    plant.step(*got, c.gap_rad.at(static_cast<double>(k) * c.period_s, gap_cursor));
    sync();
  }
  res.end = loop.end();
  res.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  rig.deactivate();
  return res;
}

// The CAN rig in lock-step with `side` (encoder counts both ways).
inline LockstepResult run_lockstep(const bench::Campaign& c, const std::string& run, LockstepSide& side,
                                   const std::string& rig_text, const drv::CanTransportFactory& can_transport) {
  const auto through_counts = [](double rad) { return kUnits.to_rad(kUnits.to_counts(rad)); };
  return run_lockstep_on(c, run, side.plant, side.sync, rig_text, can_transport, through_counts, through_counts);
}

// The Modbus rig's simulator side for the lock-step chain: the plant behind a Modbus drive and a
// Modbus transducer emulator on ephemeral TCP ports.
struct ModbusLockstepSide {
  explicit ModbusLockstepSide(const bench::Campaign& c)
      : plant(c),
        drive_map(drv::RegisterMap::load(source_path("drivers/configs/modbus_drive_map.yaml"))),
        drive(SimulatorSide::tcp(0), drive_map, plant),
        transducer(SimulatorSide::tcp(0), drv::RegisterMap::load(source_path("drivers/configs/modbus_transducer_map.yaml")),
                   plant) {}
  // A value through one of the drive's registers, as the far side decodes it.
  double through(const std::string& reg, double physical) const {
    const drv::Register& r = drive_map.at(reg);
    std::uint16_t words[4] = {};
    r.encode(physical, words);
    return r.decode(words);
  }
  LockstepPlant plant;
  drv::RegisterMap drive_map;
  drv::ModbusDriveEmulator drive;
  drv::ModbusTransducerEmulator transducer;
};

inline std::string lockstep_modbus_rig_yaml(const ModbusLockstepSide& s) {
  const RigOptions o = lockstep_rig_options();
  const auto device = [](int port, const std::string& map) {
    return "    modbus: {link: {transport: tcp, host: 127.0.0.1, port: " + std::to_string(port) +
           ", poll_period_ms: 1, response_timeout_ms: 1000, reconnect: {initial_ms: 20, max_ms: 200}},\n"
           "             register_map: " +
           source_path("drivers/configs/" + map).string() +
           "}\n"
           "    max_age_ms: 4\n";
  };
  return rig_yaml("modbus", device(s.drive.port(), "modbus_drive_map.yaml"),
                  device(s.transducer.port(), "modbus_transducer_map.yaml"), o);
}

inline LockstepResult run_lockstep(const bench::Campaign& c, const std::string& run, ModbusLockstepSide& side) {
  return run_lockstep_on(
      c, run, side.plant, [] {}, lockstep_modbus_rig_yaml(side), {},
      [&side](double rad) { return side.through("actual_position", rad); },
      [&side](double rad) { return side.through("target_position", rad); });
}

// The hybrid rig in lock-step: the CiA 402 emulator is backed by `motor` (the campaign's plant,
// whose motor stands for a real one), stepped when the harness says; the rig's own simulated
// valve and chamber step in its read() with the encoder angle, as in a real run. Period k: wait
// until the client holds a TPDO newer than the last period's write showing the motor's encoder
// counts -> cycle -> wait until the emulator handed target k to the motor -> step it -> SYNC.
inline LockstepResult run_lockstep_hybrid(
    const bench::Campaign& c, const std::string& run, LockstepPlant& motor, const std::function<void()>& sync_fn,
    const std::string& rig_text, const drv::CanTransportFactory& can_transport,
    const std::function<void(std::size_t, bench::SpscRing<bench::LoopRequest>&)>& before_cycle = {}) {
  LockstepResult res;
  const bench::RunSpec* spec = nullptr;
  for (const auto& r : c.runs) {
    if (r.name == run) spec = &r;
  }
  TempDir dir;
  const bench::RigConfig rc = bench::load_rig_config(dir.write("rigs/lockstep.yaml", rig_text));
  const auto owned_rig = make_device_rig(rc, can_transport);
  bench::DeviceRig& rig = *owned_rig;
  rig.configure({&c, c.period_s, c.reference_pa.at(0.0), c.gap_rad.at(0.0)});
  rig.activate();
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(c.period_s));
  const auto n = static_cast<std::size_t>(std::lround(c.duration_s / c.period_s));
  bench::SpscRing<bench::TelemetryRecord> telemetry(n + 16);
  bench::SpscRing<bench::LoopEvent> events(1024);
  bench::SpscRing<bench::LoopRequest> requests(16);
  const drv::DriveUnits& u = rc.devices.drive_config<drv::Cia402Config>()->units;
  const auto through_counts = [&u](double rad) { return u.to_rad(u.to_counts(rad)); };
  // The rig's frame: encoder angle minus the offset it took at configure (the settled plant's motor).
  const double offset = through_counts(motor.signals().theta_motor_rad) - motor.signals().theta_motor_rad;
  Clock::time_point seen{}, synced{}, wrote{};
  const auto sync = [&] {
    synced = Clock::now();
    sync_fn();
  };
  const auto drive_shows_motor = [&] {
    const double want = through_counts(motor.signals().theta_motor_rad);
    const drv::DriveFeedback fb = rig.drive_feedback();
    const auto t = Clock::now();
    if (fb.valid && fb.rx_time > wrote && fb.position_rad == want) {
      seen = t;
      return true;
    }
    if (t - synced > std::chrono::milliseconds(1)) sync();
    return false;
  };
  const auto t0 = Clock::now();
  if (!wait_state(drive_shows_motor)) {
    res.error = "the drive never showed the settled motor: " + std::string(rig.health().last_error_text());
    rig.deactivate();
    return res;
  }
  bench::RunLoop loop(c, *spec, rig, rc.safety, rc.loop, period, telemetry, events, requests);
  loop.begin(seen);
  bench::Schedule::Cursor gap_cursor;
  for (std::size_t k = 0;; ++k) {
    if (k > 0 && !wait_state(drive_shows_motor)) {
      res.error =
          "period " + std::to_string(k) + ": the drive did not show the motor: " + std::string(rig.health().last_error_text());
      break;
    }
    if (before_cycle) before_cycle(k, requests);  // operator requests, as the API would push them
    loop.cycle(seen, seen);
    const bool more = loop.finish_cycle(seen);
    wrote = Clock::now();  // after the write's SYNC: the next period's TPDO must come later
    bench::TelemetryRecord rec;
    if (telemetry.pop(&rec, 1) != 1) {
      res.error = "period " + std::to_string(k) + ": no telemetry row";
      break;
    }
    res.rows.push_back(rec);
    if ((rec.flags & bench::kFlagReadMissed) != 0 && res.missed++ == 0)
      res.first_miss = "period " + std::to_string(k) + ": " + std::string(rig.health().last_error_text());
    if (!more) break;
    const double want = through_counts(rec.theta_target_rad + offset);
    std::optional<double> got;
    if (!wait_state([&] { return (got = motor.enabled_target()) && *got == want; })) {
      res.error = "period " + std::to_string(k) + ": the drive never got the target";
      break;
    }
    motor.step(*got, c.gap_rad.at(static_cast<double>(k) * c.period_s, gap_cursor));
    sync();
  }
  res.end = loop.end();
  res.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  rig.deactivate();
  return res;
}

// The largest differences of a lock-step run to the pure simulation, row by row.
struct LockstepDiff {
  std::size_t rows = 0;
  double p_max_abs_pa = 0, p_rms_pa = 0, motor_max_abs_rad = 0, cmd_max_abs_rad = 0;
  double percent = 0;  // RMS pressure difference in % of the reference's range
};
inline LockstepDiff compare_lockstep(const bench::Campaign& c, const std::string& run,
                                     const std::vector<bench::TelemetryRecord>& rows) {
  const bench::RunSpec* spec = nullptr;
  for (const auto& r : c.runs) {
    if (r.name == run) spec = &r;
  }
  std::vector<bench::StepRecord> sim;
  bench::simulate_run(c, *spec, [&](const bench::TelemetryRecord& r) { sim.push_back(r.step); });
  LockstepDiff d;
  d.rows = std::min(rows.size(), sim.size());
  double sum = 0, lo = 1e300, hi = -1e300;
  for (std::size_t i = 0; i < d.rows; ++i) {
    const auto& a = rows[i].step;
    const auto& b = sim[i];
    EXPECT_EQ(a.t_s, b.t_s) << "row " << i;
    const double e = a.p_meas_pa - b.p_meas_pa;
    sum += e * e;
    d.p_max_abs_pa = std::max(d.p_max_abs_pa, std::abs(e));
    d.motor_max_abs_rad = std::max(d.motor_max_abs_rad, std::abs(a.theta_motor_rad - b.theta_motor_rad));
    d.cmd_max_abs_rad = std::max(d.cmd_max_abs_rad, std::abs(a.theta_cmd_rad - b.theta_cmd_rad));
    lo = std::min(lo, b.p_ref_pa);
    hi = std::max(hi, b.p_ref_pa);
  }
  d.p_rms_pa = std::sqrt(sum / static_cast<double>(std::max<std::size_t>(d.rows, 1)));
  d.percent = 100 * d.p_rms_pa / (hi - lo);
  return d;
}

}  // namespace hil::test
