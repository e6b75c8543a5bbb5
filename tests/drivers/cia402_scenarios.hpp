// Client-against-emulator scenarios, run on the in-process loopback bus (unit) and on a real
// vcan0 (vcan). A fixture supplies the transport factory; the bodies are the same.
#pragma once

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "hil/drv/cia402_drive.hpp"
#include "hil/drv/cia402_emulator.hpp"
#include "hil/drv/cia402_probe.hpp"
#include "servo_test_model.hpp"

namespace hil::drv::test {

using namespace std::chrono_literals;

// Waits (generously: the vcan suite runs under TCG emulation on a loaded machine) for `pred`.
inline bool eventually(const std::function<bool()>& pred, std::chrono::milliseconds limit = 15s) {
  const auto until = Clock::now() + limit;
  while (!pred()) {
    if (Clock::now() > until) return false;
    std::this_thread::sleep_for(2ms);
  }
  return true;
}

inline Cia402Config test_config(std::uint8_t node) {
  Cia402Config c;
  c.node_id = node;
  c.units = {4096, 10.0, 1};  // 40960 counts per valve revolution
  c.sync_period = 2ms;
  c.heartbeat_producer = 50ms;
  c.heartbeat_timeout = 1000ms;  // generous: a late heartbeat under load is not a lost one
  c.boot_timeout = 10s;
  c.sdo_timeout = 500ms;
  c.sdo_retries = 2;
  c.transition_timeout = 10s;
  return c;
}

// A 1 ms loop on its own thread, as the bench will run: writes `target` and reads feedback.
class TestLoop {
 public:
  explicit TestLoop(Cia402Drive& drive) : drive_(drive), thread_([this] { run(); }) {}
  ~TestLoop() {
    stop_ = true;
    thread_.join();
  }
  std::atomic<double> target_rad{0.0};
  std::atomic<bool> enable{true};
  std::atomic<bool> fault_reset{false};
  std::atomic<double> position_rad{kNaN};
  // A hung loop: no read(), no write() while set (the thread sleeps its periods away).
  std::atomic<bool> paused{false};

 private:
  void run() {
    auto next = Clock::now();
    while (!stop_) {
      next += 1ms;
      const auto now = Clock::now();
      if (paused) {
        std::this_thread::sleep_until(next);
        continue;
      }
      position_rad = drive_.read(now, 1ms).position_rad;
      drive_.write(now, 1ms, {target_rad.load(), enable.load(), fault_reset.load()});
      std::this_thread::sleep_until(next);
    }
  }
  Cia402Drive& drive_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// One drive on the bus, its client, and the model behind the emulator.
struct Rig {
  Rig(const CanTransportFactory& factory, Cia402Config cfg, const std::function<void(Cia402EmulatorConfig&)>& variant = {})
      : emulator(emulator_config(cfg, variant), model, factory), client(cfg, factory) {}
  static Cia402EmulatorConfig emulator_config(const Cia402Config& cfg,
                                              const std::function<void(Cia402EmulatorConfig&)>& variant) {
    Cia402EmulatorConfig e{cfg.interface, cfg.node_id, cfg.units};
    if (variant) variant(e);
    return e;
  }
  FirstOrderServoTestModel model{0.01, 20.0, 0.25};
  Cia402DriveEmulator emulator;
  Cia402Drive client;
};

inline void boots_to_operation_enabled(const CanTransportFactory& f, std::uint8_t node) {
  Rig r(f, test_config(node));
  r.client.configure();
  EXPECT_EQ(r.emulator.nmt_state(), canopen::NmtState::operational);
  // The mapping the client wrote is in the drive's dictionary, per CiA 301 / CiA 402.
  EXPECT_EQ(r.emulator.object(0x1600, 0), 2u);
  EXPECT_EQ(r.emulator.object(0x1600, 1), 0x60400010u);
  EXPECT_EQ(r.emulator.object(0x1600, 2), 0x607A0020u);
  EXPECT_EQ(r.emulator.object(0x1A00, 1), 0x60410010u);
  EXPECT_EQ(r.emulator.object(0x1A00, 2), 0x60640020u);
  EXPECT_EQ(r.emulator.object(0x1400, 1), 0x200u + node);
  EXPECT_EQ(r.emulator.object(0x1800, 1), 0x180u + node);
  EXPECT_EQ(r.emulator.object(0x1800, 2), 1u);
  EXPECT_EQ(r.emulator.object(0x1401, 1).value() & canopen::kCobIdInvalid, canopen::kCobIdInvalid);
  EXPECT_EQ(r.emulator.object(0x6060, 0), 8u);
  EXPECT_EQ(r.emulator.object(0x1017, 0), 50u);
  // The position read at configure time is the model's start, 0.25 rad.
  EXPECT_NEAR(r.client.read(Clock::now(), 1ms).position_rad, 0.25, 1e-3);
  r.client.activate();
  EXPECT_EQ(r.client.state(), cia402::State::operation_enabled);
  EXPECT_TRUE(eventually([&] { return r.emulator.state() == cia402::State::operation_enabled; }));
  const auto fb = r.client.read(Clock::now(), 1ms);
  EXPECT_TRUE(fb.enabled);
  EXPECT_FALSE(fb.fault);
  EXPECT_EQ(fb.statusword & 0x6F, 0x27);
  EXPECT_NEAR(fb.position_rad, 0.25, 2e-3);  // enabling did not make the drive jump
  const auto h = r.client.health();
  EXPECT_TRUE(h.connected);
  EXPECT_EQ(h.nmt_state, 0x05);
  EXPECT_GT(h.pdo_received, 0u);
  r.client.deactivate();
  // Issue 50: a normal end is switch on disabled (it was switched on, left to the drive's consumer).
  EXPECT_EQ(r.client.state(), cia402::State::switch_on_disabled);
  EXPECT_EQ(r.emulator.state(), cia402::State::switch_on_disabled);
  const SwitchOff off = r.client.last_switch_off();
  EXPECT_EQ(off.path, "pdo");
  EXPECT_EQ(off.asked_by, "deactivate()");
  EXPECT_TRUE(off.off);
  EXPECT_EQ(off.state, "switch on disabled");
}

inline void csp_position_tracking(const CanTransportFactory& f, std::uint8_t node) {
  Rig r(f, test_config(node));
  r.client.configure();
  r.client.activate();
  TestLoop loop(r.client);
  loop.target_rad = 0.25;
  for (double target : {0.5, -0.3, 0.1}) {
    loop.target_rad = target;
    // The model (20 rad/s, 10 ms lag) gets there well within the wait; the client reads it
    // back through TPDO counts with a resolution of 2π/40960 rad.
    EXPECT_TRUE(eventually([&] { return std::abs(loop.position_rad - target) < 1e-3; }))
        << "target " << target << " position " << loop.position_rad.load();
    EXPECT_NEAR(r.model.target_rad(), target, 2e-4);  // the target arrived in counts, converted back
  }
  EXPECT_GT(r.emulator.syncs_seen(), 10u);
  EXPECT_EQ(r.client.health().tx_failed, 0u);
}

inline void heartbeat_loss_detected(const CanTransportFactory& f, std::uint8_t node) {
  auto cfg = test_config(node);
  Rig r(f, cfg);
  r.client.configure();
  EXPECT_FALSE(r.client.health().heartbeat_lost);
  r.emulator.stop_heartbeat(true);
  const auto t0 = Clock::now();
  ASSERT_TRUE(eventually([&] { return r.client.health().heartbeat_lost; }));
  // Not before the configured timeout (no upper bound asserted: the machine may be loaded).
  EXPECT_GE(Clock::now() - t0, cfg.heartbeat_timeout - cfg.heartbeat_producer);
  const auto h = r.client.health();
  EXPECT_TRUE(h.fault);
  EXPECT_FALSE(h.connected);
  EXPECT_GT(h.heartbeat_age, cfg.heartbeat_timeout);
  EXPECT_NE(h.last_error_text().find("heartbeat lost"), std::string_view::npos) << h.last_error_text();
  EXPECT_TRUE(r.client.read(Clock::now(), 1ms).fault);
  r.emulator.stop_heartbeat(false);
  EXPECT_TRUE(eventually([&] { return !r.client.health().heartbeat_lost; }));
  // Issue 38 item 9: the heartbeat came back, but the client still holds the drive (quick stop /
  // disable voltage) for the loss: that is a fault, and its cause is kept. It used to read as no
  // fault at all, so a rig saw a drive that "switched itself off".
  const auto back = r.client.health();
  EXPECT_TRUE(back.fault);
  EXPECT_TRUE(r.client.read(Clock::now(), 1ms).fault);
  EXPECT_NE(back.fault_cause_text().find("heartbeat lost (none for 1000 ms)"), std::string_view::npos) << back.fault_cause_text();
  EXPECT_NE(back.last_error_text().find("heartbeat resumed after "), std::string_view::npos) << back.last_error_text();
  r.client.reset_fault();  // the explicit request ends the hold
  EXPECT_TRUE(eventually([&] { return !r.client.read(Clock::now(), 1ms).fault; })) << r.client.health().last_error_text();
  EXPECT_TRUE(r.client.health().fault_cause_text().empty()) << r.client.health().fault_cause_text();
}

// Issue 38 item 10: the drive watches the bench. configure() writes the drive's consumer
// heartbeat time 0x1016 (bits 16-23 the bench's node id, bits 0-15 the time in ms) and its abort
// connection option code 0x6007, and the client produces its heartbeat from then on. A client
// that stops without a word (its I/O thread gone with it: what a killed bench process looks like
// on the bus) puts the drive into `want` by 0x6007, no sooner than the consumer time after the
// bench's last heartbeat. The drive used to hold its last target, powered, for ever.
inline void drive_watches_the_bench(const CanTransportFactory& f, std::uint8_t node, std::int16_t on_loss, cia402::State want) {
  auto cfg = test_config(node);
  cfg.bench_heartbeat.node_id = 100;
  cfg.bench_heartbeat.producer = 50ms;
  cfg.bench_heartbeat.drive_timeout = 600ms;  // a loaded machine may starve the client's thread for 100 ms
  cfg.bench_heartbeat.on_loss = on_loss;
  FirstOrderServoTestModel model{0.01, 20.0, 0.25};
  Cia402DriveEmulator emulator(Rig::emulator_config(cfg, {}), model, f);
  auto client = std::make_unique<Cia402Drive>(cfg, f);
  client->configure();
  EXPECT_EQ(emulator.object(0x1016, 1), (100u << 16) | 600u);
  EXPECT_EQ(emulator.object(0x6007, 0), static_cast<std::uint32_t>(on_loss));
  client->activate();
  {
    TestLoop loop(*client);
    loop.target_rad = 0.3;
    ASSERT_TRUE(eventually([&] { return std::abs(loop.position_rad - 0.3) < 1e-3; }));
    EXPECT_EQ(emulator.state(), cia402::State::operation_enabled);
    EXPECT_EQ(emulator.heartbeat_consumer_events(), 0u);  // the bench is alive: no event
  }
  client.reset();  // the bench dies: no deactivate(), no more frames
  ASSERT_TRUE(eventually([&] { return emulator.heartbeat_consumer_events() > 0; }, 20s));
  const auto event = emulator.last_consumer_event();
  ASSERT_TRUE(event.has_value());
  EXPECT_EQ(event->node, 100);
  EXPECT_GE(event->silence, 600ms);  // not before the consumer time
  EXPECT_EQ(event->state_after, want) << cia402::to_string(event->state_after);
  EXPECT_TRUE(eventually([&] { return emulator.state() == want; })) << cia402::to_string(emulator.state());
  EXPECT_EQ(emulator.heartbeat_consumer_events(), 1u);
  std::printf("bench heartbeat lost: the drive reacted %.1f ms after the bench's last heartbeat (consumer time 600 ms): %s\n",
              std::chrono::duration<double, std::milli>(event->silence).count(),
              std::string(cia402::to_string(event->state_after)).c_str());
}

// The number after `key` in `text` (-1 when absent): "hung for 1502 ms" -> 1502.
inline long number_after(const std::string& text, const std::string& key) {
  const auto at = text.find(key);
  return at == std::string::npos ? -1 : std::atol(text.c_str() + at + key.size());
}

// Issue 50: the bench's heartbeat means "the control loop is alive". A loop that stops writing
// (a controller that never returns, a lock) while it runs the drive makes the client's I/O thread
// quick-stop the drive itself past loop_hang_bound and stop the bench's heartbeat, so a drive's
// consumer trips too; a drive without a consumer is stopped by the quick stop alone. When the
// loop comes back the fault's cause says how long it was gone.
inline void a_hung_loop_stops_the_drive(const CanTransportFactory& f, std::uint8_t node, bool consumer) {
  auto cfg = test_config(node);
  cfg.loop_hang_bound = 600ms;  // a loaded machine may starve the test's loop thread for 100 ms
  cfg.bench_heartbeat.producer = 50ms;
  cfg.bench_heartbeat.drive_timeout = 600ms;
  cfg.bench_heartbeat.required = consumer;
  Rig r(f, cfg, [consumer](Cia402EmulatorConfig& e) { e.heartbeat_consumer = consumer; });
  r.client.configure();
  r.client.activate();
  TestLoop loop(r.client);
  loop.target_rad = 0.3;
  ASSERT_TRUE(eventually([&] { return std::abs(loop.position_rad - 0.3) < 1e-3; }));
  std::this_thread::sleep_for(800ms);  // longer than the bound: a running loop is not hung
  ASSERT_FALSE(r.client.health().fault) << r.client.health().last_error_text();
  const auto hung = Clock::now();
  loop.paused = true;
  ASSERT_TRUE(eventually([&] { return r.emulator.state() == cia402::State::switch_on_disabled; }, 20s))
      << cia402::to_string(r.emulator.state());
  const auto stopped = Clock::now() - hung;
  EXPECT_GE(stopped, cfg.loop_hang_bound);  // not before the bound
  // The I/O thread's own quick stop does it within the bound (and a SYNC or two); the drive's
  // consumer would by bound + consumer time: the drive is stopped by then, with margin for load.
  EXPECT_LE(stopped, cfg.loop_hang_bound + cfg.bench_heartbeat.drive_timeout + 2s);
  if (consumer) {  // the bench's heartbeat stopped with the loop: the drive's consumer trips too
    ASSERT_TRUE(eventually([&] { return r.emulator.heartbeat_consumer_events() > 0; }, 20s));
    EXPECT_GE(r.emulator.last_consumer_event()->silence, cfg.bench_heartbeat.drive_timeout);
  }
  const auto h = r.client.health();
  EXPECT_TRUE(h.fault);
  EXPECT_NE(h.fault_cause_text().find("control loop hung: no period completed for "), std::string_view::npos)
      << h.fault_cause_text();
  std::this_thread::sleep_until(hung + 2500ms);  // hung 2.5 s in all
  loop.paused = false;
  std::string cause;
  ASSERT_TRUE(eventually([&] {
    cause = std::string(r.client.health().fault_cause_text());
    return cause.find("control loop hung for ") != std::string::npos;
  })) << cause;
  const long hung_ms = number_after(cause, "control loop hung for ");
  EXPECT_GE(hung_ms, 2400) << cause;
  EXPECT_NE(cause.find("(the bench allows 600 ms)"), std::string::npos) << cause;
  EXPECT_TRUE(r.client.read(Clock::now(), 1ms).fault);  // held until a reset: the loop trips on it
  std::printf(
      "loop hung %ld ms (consumer %s): the drive reached switch on disabled %.0f ms after the loop's last write "
      "(bound 600 ms, consumer 600 ms)\n",
      hung_ms, consumer ? "on" : "off", std::chrono::duration<double, std::milli>(stopped).count());
}

// Issue 50: a drive that leaves NMT operational by itself while enabled (its 0x1029 error
// behaviour) no longer takes the cyclic controlword: the client switches it off by SDO at once
// (0x6040 written, 0x6041 read back) and reports the state read back, not the last TPDO's; where
// SDO is refused too, it stops the node (NMT) and says the state is unknown.
inline void a_drive_out_of_operational_is_switched_off(const CanTransportFactory& f, std::uint8_t node, bool sdo_refused) {
  Rig r(f, test_config(node));
  r.client.configure();
  r.client.activate();
  TestLoop loop(r.client);
  ASSERT_TRUE(eventually([&] { return r.emulator.state() == cia402::State::operation_enabled; }));
  if (sdo_refused) r.emulator.fail_sdo(cia402::kControlword, 0, 0x08000022);
  const auto left = Clock::now();
  r.emulator.enter_nmt_state(canopen::NmtState::pre_operational);
  ASSERT_TRUE(eventually([&] { return !r.client.last_switch_off().path.empty(); }, 20s));
  const SwitchOff off = r.client.last_switch_off();
  EXPECT_NE(off.asked_by.find("the drive left NMT operational"), std::string::npos) << off.asked_by;
  if (sdo_refused) {
    EXPECT_EQ(off.path, "nmt_stop");
    EXPECT_FALSE(off.off);
    EXPECT_NE(off.state.find("unknown"), std::string::npos) << off.state;
    EXPECT_TRUE(eventually([&] { return r.emulator.nmt_state() == canopen::NmtState::stopped; }));
    loop.paused = true;
    try {
      r.client.deactivate();
      ADD_FAILURE() << "deactivate() said off with the state unknown";
    } catch (const DriveError& e) {
      EXPECT_NE(std::string(e.what()).find("not switched off: nmt_stop"), std::string::npos) << e.what();
    }
    return;
  }
  EXPECT_EQ(off.path, "sdo");
  EXPECT_TRUE(off.off);
  EXPECT_EQ(off.state, "switch on disabled");
  EXPECT_EQ(r.emulator.state(), cia402::State::switch_on_disabled);
  EXPECT_EQ(r.emulator.nmt_state(), canopen::NmtState::pre_operational);  // by SDO, not by NMT
  EXPECT_EQ(r.client.state(), cia402::State::switch_on_disabled);         // the state read back, not the stale TPDO's
  std::printf(
      "drive left NMT operational while enabled: switched off by %s %.1f ms after the client saw it (%.0f ms "
      "after the drive left)\n",
      off.path.c_str(), off.after_ms, std::chrono::duration<double, std::milli>(Clock::now() - left).count());
  loop.paused = true;
  r.client.deactivate();  // already off: the record stays the client's own
  EXPECT_EQ(r.client.last_switch_off().path, "sdo");
}

inline void sdo_abort_names_object(const CanTransportFactory& f, std::uint8_t node) {
  Rig r(f, test_config(node));
  try {
    r.client.sdo_read(0x2000, 0);
    ADD_FAILURE() << "no abort";
  } catch (const SdoAbortError& e) {
    EXPECT_EQ(e.code, 0x06020000u);
    EXPECT_EQ(e.index, 0x2000);
    const std::string what = e.what();
    EXPECT_NE(what.find("0x2000:00"), std::string::npos) << what;
    EXPECT_NE(what.find("object does not exist"), std::string::npos) << what;
    EXPECT_NE(what.find("node " + std::to_string(node)), std::string::npos) << what;
  }
  // An abort in the middle of configure() names the object being configured.
  r.emulator.fail_sdo(0x6060, 0, 0x08000022);
  try {
    r.client.configure();
    ADD_FAILURE() << "configure() succeeded";
  } catch (const SdoAbortError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("SDO write 0x6060:00"), std::string::npos) << what;
    EXPECT_NE(what.find("0x08000022"), std::string::npos) << what;
    EXPECT_NE(what.find("present device state"), std::string::npos) << what;
  }
  EXPECT_GE(r.client.health().aborts_or_exceptions, 2u);
  r.emulator.clear_sdo_failures();
  r.client.configure();  // and recovers once the drive stops refusing
}

inline void emcy_enters_fault_and_resets(const CanTransportFactory& f, std::uint8_t node) {
  Rig r(f, test_config(node));
  r.client.configure();
  r.client.activate();
  r.emulator.raise_emcy(0x2310, 0x02, {0x01, 0x02, 0x03, 0x04, 0x05});
  ASSERT_TRUE(eventually([&] { return r.client.state() == cia402::State::fault; }));
  const auto fb = r.client.read(Clock::now(), 1ms);
  EXPECT_TRUE(fb.fault);
  EXPECT_FALSE(fb.enabled);
  EXPECT_EQ(fb.statusword & 0x4F, 0x08);
  ASSERT_TRUE(eventually([&] { return r.client.health().emcy_count >= 1; }));
  const auto h = r.client.health();
  EXPECT_EQ(h.last_emcy_code, 0x2310);
  EXPECT_EQ(h.last_emcy_register, 0x03);  // generic bit set by the drive with the current bit
  EXPECT_EQ(r.emulator.object(0x603F, 0), 0x2310u);
  // The EMCY is decoded by name somewhere in the error history; the newest says "fault".
  r.client.activate();  // one fault reset, then back to operation enabled
  EXPECT_EQ(r.client.state(), cia402::State::operation_enabled);
  EXPECT_TRUE(eventually([&] { return r.client.health().emcy_count >= 2; }));  // EMCY 0x0000 error reset
  EXPECT_EQ(r.client.health().last_emcy_code, 0x0000);
  EXPECT_EQ(r.emulator.object(0x603F, 0), 0u);
}

inline void sdo_timeout_retry_and_late_answer(const CanTransportFactory& f, std::uint8_t node) {
  auto cfg = test_config(node);
  cfg.sdo_timeout = 300ms;
  cfg.sdo_retries = 2;
  Rig r(f, cfg);
  EXPECT_EQ(r.client.sdo_read(0x1000, 0), 0x00020192u);
  r.emulator.set_silent(true);
  try {
    r.client.sdo_read(0x1018, 1);
    ADD_FAILURE() << "a silent drive answered";
  } catch (const DriveError& e) {
    EXPECT_NE(std::string(e.what()).find("SDO read 0x1018:01: no reply after 3 tries"), std::string::npos) << e.what();
  }
  EXPECT_GE(r.client.health().timeouts, 3u);
  r.emulator.set_silent(false);
  // Late beyond one timeout: the retry's window catches the answer.
  r.emulator.set_response_delay(400ms);
  EXPECT_EQ(r.client.sdo_read(0x1018, 2), 0x402u);
  r.emulator.set_response_delay(0us);
  EXPECT_EQ(r.client.sdo_read(0x1018, 1), 0xABCu);
}

inline void bus_off_policy(const CanTransportFactory& f, std::uint8_t node, BusOffPolicy policy) {
  auto cfg = test_config(node);
  cfg.bus_off_policy = policy;
  cfg.bus_off_recover_after = 300ms;
  cfg.heartbeat_timeout = 5000ms;  // keep the heartbeat out of this story
  // And the bench's: a bus-off client sends no heartbeat either, which the drive would take for
  // a dead bench after drive_timeout (as a real bus-off controller's drive does).
  cfg.bench_heartbeat.drive_timeout = 5000ms;
  Rig r(f, cfg);
  r.client.configure();
  r.client.activate();
  r.emulator.emulate_bus_error(EmulatedBusError::error_passive);
  ASSERT_TRUE(eventually([&] { return r.client.health().bus_state == BusState::error_passive; }));
  EXPECT_FALSE(r.client.health().fault);  // error-passive is reported, not a fault
  r.emulator.emulate_bus_error(EmulatedBusError::bus_off);
  ASSERT_TRUE(eventually([&] { return r.client.health().fault; }));
  auto h = r.client.health();
  EXPECT_NE(h.last_error_text().find("bus-off"), std::string_view::npos) << h.last_error_text();
  EXPECT_TRUE(r.client.read(Clock::now(), 1ms).fault);
  if (policy != BusOffPolicy::recover) {
    // No SYNC leaves a bus-off controller.
    std::this_thread::sleep_for(100ms);
    const auto syncs = r.emulator.syncs_seen();
    std::this_thread::sleep_for(300ms);
    EXPECT_EQ(r.emulator.syncs_seen(), syncs);
  }
  if (policy == BusOffPolicy::report) {
    r.emulator.emulate_bus_error(EmulatedBusError::restarted);
    std::this_thread::sleep_for(300ms);
    EXPECT_TRUE(r.client.health().fault) << "policy report must hold the fault until cleared";
    r.client.clear_bus_off();
  } else if (policy == BusOffPolicy::wait) {
    r.emulator.emulate_bus_error(EmulatedBusError::restarted);
  }
  ASSERT_TRUE(eventually([&] { return !r.client.health().fault; })) << r.client.health().last_error_text();
  h = r.client.health();
  EXPECT_EQ(h.bus_state, BusState::error_active);
  EXPECT_EQ(h.reconnects, 1u);
  const auto syncs = r.emulator.syncs_seen();
  EXPECT_TRUE(eventually([&] { return r.emulator.syncs_seen() > syncs + 5; }));  // SYNC resumed
  EXPECT_EQ(r.client.state(), cia402::State::operation_enabled);
}

inline void malformed_frames_are_counted(const CanTransportFactory& f, std::uint8_t node,
                                         const std::function<void(const CanFrame&)>& inject) {
  Rig r(f, test_config(node));
  r.client.configure();
  CanFrame short_emcy;
  short_emcy.id = 0x080u + node;
  short_emcy.dlc = 3;
  short_emcy.data = {0x10, 0x23, 0x02};
  inject(short_emcy);
  ASSERT_TRUE(eventually([&] { return r.client.health().malformed >= 1; }));
  EXPECT_NE(r.client.health().last_error_text().find("malformed EMCY"), std::string_view::npos)
      << r.client.health().last_error_text();
  EXPECT_EQ(r.client.health().emcy_count, 0u);
  // A valid EMCY injected from outside is decoded.
  CanFrame e;
  e.id = 0x080u + node;
  e.dlc = 8;
  e.data = {0x30, 0x81, 0x11, 0xAA, 0xBB, 0xCC, 0xDD, 0xEE};
  inject(e);
  ASSERT_TRUE(eventually([&] { return r.client.health().emcy_count == 1; }));
  const auto h = r.client.health();
  EXPECT_EQ(h.last_emcy_code, 0x8130);
  EXPECT_EQ(h.last_emcy_register, 0x11);
  const std::string text(h.last_error_text());
  EXPECT_NE(text.find("life guard or heartbeat error"), std::string::npos) << text;
  EXPECT_NE(text.find("AA BB CC DD EE"), std::string::npos) << text;
  // The client still runs.
  const auto seq = r.client.read(Clock::now(), 1ms).sequence;
  EXPECT_TRUE(eventually([&] { return r.client.read(Clock::now(), 1ms).sequence > seq + 3; }));
}

// ---- the emulator as other legal drives ---------------------------------------------------------

inline bool has_note(const Cia402Drive& c, const std::string& part) {
  for (const auto& n : c.configure_notes()) {
    if (n.find(part) != std::string::npos) return true;
  }
  return false;
}

// Configures, enables and moves the drive; `check` looks at what configure() left.
inline void variant_runs(const CanTransportFactory& f, std::uint8_t node,
                         const std::function<void(Cia402EmulatorConfig&)>& variant, const std::function<void(Rig&)>& check) {
  Rig r(f, test_config(node), variant);
  r.client.configure();
  check(r);
  r.client.activate();
  TestLoop loop(r.client);
  loop.target_rad = 0.25;
  loop.target_rad = 0.6;
  EXPECT_TRUE(eventually([&] { return std::abs(loop.position_rad - 0.6) < 1e-3; })) << loop.position_rad.load();
  EXPECT_FALSE(r.client.health().fault) << r.client.health().last_error_text();
}

// CiA 301 asks for one PDO each way; a drive with two has no 0x1402/0x1403/0x1802/0x1803.
inline void variant_two_pdos_each_way(const CanTransportFactory& f, std::uint8_t node) {
  variant_runs(
      f, node, [](Cia402EmulatorConfig& e) { e.pdos = 2; },
      [](Rig& r) {
        EXPECT_FALSE(r.emulator.object(0x1402, 1).has_value());
        EXPECT_EQ(r.emulator.object(0x1401, 1).value() & canopen::kCobIdInvalid, canopen::kCobIdInvalid);  // the one it has: off
        EXPECT_EQ(r.emulator.object(0x1801, 1).value() & canopen::kCobIdInvalid, canopen::kCobIdInvalid);
        EXPECT_TRUE(has_note(r.client, "0x1402:01 absent"));
        EXPECT_TRUE(has_note(r.client, "0x1803:01 absent"));
      });
}

// 0x60C2 is optional in CiA 402: a drive without it takes its period from SYNC.
inline void variant_no_interpolation_period(const CanTransportFactory& f, std::uint8_t node) {
  variant_runs(
      f, node, [](Cia402EmulatorConfig& e) { e.interpolation_period = false; },
      [](Rig& r) {
        EXPECT_FALSE(r.emulator.object(0x60C2, 1).has_value());
        EXPECT_TRUE(has_note(r.client, "0x60C2:01 absent"));
      });
}

// 0x6061 follows 0x6060 5 ms later: the client polls it (up to transition_ms).
inline void variant_delayed_mode_display(const CanTransportFactory& f, std::uint8_t node) {
  variant_runs(
      f, node, [](Cia402EmulatorConfig& e) { e.mode_display_delay = 5ms; },
      [](Rig& r) {
        EXPECT_EQ(r.emulator.object(0x6061, 0), 8u);
        EXPECT_TRUE(r.client.configure_notes().empty());
      });
  // A drive that never shows the mode fails after transition_ms, naming the object.
  auto cfg = test_config(node);
  cfg.transition_timeout = 300ms;
  Rig r(f, cfg, [](Cia402EmulatorConfig& e) { e.mode_display_delay = 60s; });
  try {
    r.client.configure();
    ADD_FAILURE() << "configured without the mode";
  } catch (const DriveError& e) {
    EXPECT_NE(std::string(e.what()).find("within 300 ms (0x6061:00 = 0)"), std::string::npos) << e.what();
  }
}

// Following error monitoring: configure writes 0x6065/0x6066 from the client's limits; a step
// the drive cannot follow raises EMCY 0x8611, and the fault text names the decoded class, the
// error register and the manufacturer bytes (not just "entered fault").
inline void variant_following_error(const CanTransportFactory& f, std::uint8_t node) {
  auto cfg = test_config(node);
  cfg.limits.following_error_window_rad = 0.05;
  cfg.limits.following_error_timeout = 20ms;
  Rig r(f, cfg, [](Cia402EmulatorConfig& e) { e.following_error = true; });
  r.client.configure();
  EXPECT_EQ(r.emulator.object(0x6065, 0), static_cast<std::uint32_t>(std::lround(0.05 / cfg.units.rad_per_count())));
  EXPECT_EQ(r.emulator.object(0x6066, 0), 20u);
  r.client.activate();
  {
    TestLoop loop(r.client);
    loop.target_rad = 0.25;
    loop.target_rad = 0.3;  // within reach: no fault
    ASSERT_TRUE(eventually([&] { return std::abs(loop.position_rad - 0.3) < 1e-3; }));
    EXPECT_FALSE(r.client.health().fault) << r.client.health().last_error_text();
    loop.target_rad = 5.0;  // 4.7 rad at 20 rad/s: 235 ms outside a 0.05 rad window
    ASSERT_TRUE(eventually([&] { return r.client.state() == cia402::State::fault; }));
  }
  ASSERT_TRUE(eventually([&] { return r.client.health().last_emcy_code == 0x8611; }));
  const auto h = r.client.health();
  const std::string text(h.last_error_text());
  EXPECT_NE(text.find("drive entered fault: EMCY 0x8611 (following error)"), std::string::npos) << text;
  EXPECT_NE(text.find("register 0x21 (generic, device profile)"), std::string::npos) << text;
  EXPECT_NE(text.find("manufacturer"), std::string::npos) << text;
  EXPECT_TRUE(r.client.read(Clock::now(), 1ms).fault);
}

// A quick stop ramps down at 0x6085 (written from the client's limits), then switch on disabled.
inline void variant_quick_stop_ramp(const CanTransportFactory& f, std::uint8_t node) {
  auto cfg = test_config(node);
  cfg.limits.quick_stop_deceleration_rad_s2 = 100.0;
  Rig r(f, cfg, [](Cia402EmulatorConfig& e) { e.quick_stop_ramp = true; });
  r.client.configure();
  EXPECT_EQ(r.emulator.object(0x605A, 0), 2u);
  EXPECT_EQ(r.emulator.object(0x6085, 0), static_cast<std::uint32_t>(std::lround(100.0 / cfg.units.rad_per_count())));
  r.client.activate();
  TestLoop loop(r.client);
  loop.target_rad = 0.25;
  loop.target_rad = 20.0;  // the model moves at its 20 rad/s limit
  ASSERT_TRUE(eventually([&] { return loop.position_rad > 1.0; }));
  r.client.quick_stop();
  EXPECT_EQ(r.emulator.state(), cia402::State::switch_on_disabled);
  // From v0 (about 20 rad/s) at 100 rad/s^2 the motor stops v0^2 / 200 (about 2 rad) beyond where
  // the ramp began, however late the command reached the drive on a busy machine.
  const auto ramp = r.emulator.quick_stop_ramp_start();
  ASSERT_TRUE(ramp.has_value());
  EXPECT_GT(ramp->velocity_rad_s, 10.0) << "the motor was not moving when the quick stop came";
  const double expected_rad = ramp->velocity_rad_s * ramp->velocity_rad_s / (2 * 100.0);
  std::this_thread::sleep_for(50ms);
  const double stopped = r.client.read(Clock::now(), 1ms).position_rad;
  EXPECT_GT(stopped - ramp->position_rad, 0.5 * expected_rad) << "no ramp: stopped at once";
  EXPECT_NEAR(stopped - ramp->position_rad, expected_rad, 0.1 * expected_rad);
  std::this_thread::sleep_for(50ms);
  EXPECT_NEAR(r.client.read(Clock::now(), 1ms).position_rad, stopped, 1e-3);  // and stays
}

// probe() reads what each variant has, without moving it: no NMT start, no SYNC, no enable.
inline void probe_variants(const CanTransportFactory& f, std::uint8_t node) {
  {
    Rig r(f, test_config(node));
    const Cia402Probe p = probe(r.client);
    EXPECT_TRUE(p.usable) << p.report();
    EXPECT_EQ(p.rpdos, 4);
    EXPECT_EQ(p.tpdos, 4);
    EXPECT_TRUE(p.csp_supported);
    ASSERT_NE(p.find(0x1018, 1), nullptr);
    EXPECT_EQ(p.find(0x1018, 1)->value, 0xABCu);
    EXPECT_EQ(p.find(0x6502, 0)->value, 0x81u);
    EXPECT_FALSE(p.find(0x6065, 0)->value.has_value());
    const std::string rep = p.report();
    EXPECT_NE(rep.find("0x6065/0x6066 following error window and timeout (optional"), std::string::npos) << rep;
    // Issue 50: 0x1006, which configure() writes, is read and planned.
    EXPECT_NE(rep.find("0x1006 communication cycle period = the SYNC period"), std::string::npos) << rep;
    EXPECT_TRUE(p.find(0x1006, 0)->value.has_value());
    EXPECT_NE(rep.find("verdict: usable"), std::string::npos) << rep;
    // Nothing moved: the drive is where it booted, pre-operational, no SYNC seen.
    EXPECT_EQ(r.emulator.nmt_state(), canopen::NmtState::pre_operational);
    EXPECT_EQ(r.emulator.syncs_seen(), 0u);
    EXPECT_NE(r.emulator.state(), cia402::State::operation_enabled);
  }
  {
    Rig r(f, test_config(node), [](Cia402EmulatorConfig& e) {
      e.pdos = 2;
      e.interpolation_period = false;
      e.following_error = true;
      e.quick_stop_ramp = true;
    });
    const Cia402Probe p = probe(r.client);
    EXPECT_TRUE(p.usable) << p.report();
    EXPECT_EQ(p.rpdos, 2);
    EXPECT_EQ(p.tpdos, 2);
    EXPECT_EQ(p.find(0x6065, 0)->value, 0xFFFFFFFFu);
    EXPECT_EQ(p.find(0x6066, 0)->value, 10u);
    const std::string rep = p.report();
    EXPECT_NE(rep.find("PDOs: 2 RPDO, 2 TPDO"), std::string::npos) << rep;
    EXPECT_NE(rep.find("0x60C2 interpolation time period (optional"), std::string::npos) << rep;
    EXPECT_NE(rep.find("quick stop option code 0x605A = 2 (quick stop ramp)"), std::string::npos) << rep;
    EXPECT_EQ(r.emulator.syncs_seen(), 0u);
  }
  {  // Issue 50: a drive without 0x605A and 0x1006 (both optional): each listed as lacking
    Rig r(f, test_config(node));
    r.emulator.fail_sdo(0x605A, 0, 0x06020000);
    r.emulator.fail_sdo(0x1006, 0, 0x06020000);
    const Cia402Probe p = probe(r.client);
    EXPECT_TRUE(p.usable) << p.report();
    const std::string rep = p.report();
    EXPECT_NE(rep.find("0x605A quick stop option code (optional"), std::string::npos) << rep;
    EXPECT_NE(rep.find("0x1006 communication cycle period (optional"), std::string::npos) << rep;
  }
}

// EMCY then fault: the decoded EMCY stays in the fault text whatever its class.
inline void emcy_text_survives_the_fault(const CanTransportFactory& f, std::uint8_t node) {
  Rig r(f, test_config(node));
  r.client.configure();
  r.client.activate();
  r.emulator.raise_emcy(0x8611, 0x20, {0x01, 0x02, 0x03, 0x04, 0x05});
  ASSERT_TRUE(eventually([&] { return r.client.state() == cia402::State::fault; }));
  ASSERT_TRUE(eventually([&] { return r.client.health().last_emcy_code == 0x8611; }));
  const std::string text(r.client.health().last_error_text());
  EXPECT_NE(text.find("EMCY 0x8611 (following error), register 0x21 (generic, device profile), manufacturer 01 02 03 04 05"),
            std::string::npos)
      << text;
}

}  // namespace hil::drv::test
