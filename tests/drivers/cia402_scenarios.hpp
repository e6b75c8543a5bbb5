// Client-against-emulator scenarios, run on the in-process loopback bus (unit) and on a real
// vcan0 (vcan). A fixture supplies the transport factory; the bodies are the same.
#pragma once

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <thread>

#include "hil/drv/cia402_drive.hpp"
#include "hil/drv/cia402_emulator.hpp"
#include "hil/drv/servo_test_model.hpp"

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

 private:
  void run() {
    auto next = Clock::now();
    while (!stop_) {
      next += 1ms;
      const auto now = Clock::now();
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
  Rig(const CanTransportFactory& factory, Cia402Config cfg)
      : emulator(Cia402EmulatorConfig{cfg.interface, cfg.node_id, cfg.units}, model, factory),
        client(cfg, factory) {}
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
  EXPECT_EQ(r.client.state(), cia402::State::switched_on);
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
  EXPECT_FALSE(r.client.read(Clock::now(), 1ms).fault);
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

}  // namespace hil::drv::test
