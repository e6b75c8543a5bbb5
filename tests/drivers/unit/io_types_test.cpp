#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

#include <thread>

#include "hil/config.hpp"
#include "hil/drv/cia402_drive.hpp"
#include "hil/drv/cia402_emulator.hpp"
#include "hil/drv/io_types.hpp"

namespace hil::drv {
namespace {

struct Pair {
  std::uint64_t a = 0, b = 0, c = 0;
};

TEST(Mailbox, ReaderNeverSeesATornValue) {
  Mailbox<Pair> box;
  std::atomic<bool> reading{false}, stop{false};
  std::thread writer([&] {
    while (!reading) std::this_thread::yield();  // overlap with the reader, or nothing is tested
    for (std::uint64_t i = 1; i < 200000; ++i) box.store({i, i * 3, i * 7});
    stop = true;
  });
  std::uint64_t last = 0, reads = 0;
  reading = true;
  for (bool done = false; !done;) {
    done = stop;  // one more load after the writer finished
    const Pair p = box.load();
    ASSERT_EQ(p.b, p.a * 3);
    ASSERT_EQ(p.c, p.a * 7);
    ASSERT_GE(p.a, last);  // newest value wins, never goes back
    last = p.a;
    ++reads;
  }
  writer.join();
  EXPECT_EQ(box.load().a, 199999u);
  EXPECT_GT(reads, 0u);
}

TEST(DeviceHealth, LastErrorIsTruncatedNotOverflowed) {
  DeviceHealth h;
  h.set_last_error(std::string(500, 'x'));
  EXPECT_EQ(h.last_error_text().size(), h.last_error.size() - 1);
}

TEST(DriveUnits, CountsAndRadians) {
  DriveUnits u{4096, 10.0, -1};
  EXPECT_EQ(u.to_counts(2 * 3.14159265358979), -40960);
  EXPECT_NEAR(u.to_rad(-40960), 2 * 3.14159265358979, 1e-12);
  EXPECT_EQ(u.to_counts(1e12), INT32_MIN);  // saturates (sign -1)
  EXPECT_EQ(u.to_counts(kNaN), INT32_MIN);
}

TEST(Cia402Config, ReadsTheExampleFile) {
  const auto c = Cia402Config::load(HIL_SOURCE_DIR "/drivers/configs/cia402_drive.yaml");
  EXPECT_EQ(c.interface, "vcan0");
  EXPECT_EQ(c.node_id, 5);
  EXPECT_EQ(c.sync_period, std::chrono::microseconds(1000));
  EXPECT_EQ(c.heartbeat_timeout, std::chrono::milliseconds(350));
  EXPECT_EQ(c.units.counts_per_rev, 131072);
  EXPECT_EQ(c.bus_off_policy, BusOffPolicy::wait);
}

TEST(Cia402Config, ErrorsNameFileLineAndKey) {
  const auto bad = cfg::Node::load_string("interface: vcan0\nnode_id: 200\n", "drive.yaml");
  try {
    Cia402Config::from_yaml(bad);
    FAIL();
  } catch (const cfg::Error& e) {
    EXPECT_NE(std::string(e.what()).find("drive.yaml:2:1: node_id: a CANopen node id is 1..127"), std::string::npos) << e.what();
  }
  const auto typo = cfg::Node::load_string("interface: vcan0\nnode_id: 2\nheartbeat: {producer_ms: 100, timeout: 5}\n", "d.yaml");
  try {
    Cia402Config::from_yaml(typo);
    FAIL();
  } catch (const cfg::Error& e) {
    EXPECT_NE(std::string(e.what()).find("did you mean 'timeout_ms'"), std::string::npos) << e.what();
  }
}

// Values the client used to accept and then bend: a producer time 0x1017 (16 bit) cannot hold
// (65536 was written as 0: heartbeat off), interface names the kernel refuses (found only at
// open, without the file), a bitrate no CAN controller runs, waits that overflow the clock.
TEST(Cia402Config, ValuesTheBusCannotCarryAreRefusedWithFileLineAndKey) {
  for (const auto& [text, want] : std::vector<std::pair<std::string, std::string>>{
           {"interface: vcan0\nnode_id: 2\nheartbeat: {producer_ms: 65536, timeout_ms: 70000}",
            "d.yaml:3:13: heartbeat.producer_ms: must be 1..65535 ms (0x1017 is 16 bit: 65536 would be written as 0, which turns "
            "the "
            "heartbeat off), got '65536'"},
           {"interface: averyveryverylongcan0\nnode_id: 2", "d.yaml:1:1: interface: a network interface name is 1..15"},
           {"interface: ''\nnode_id: 2", "d.yaml:1:1: interface: a network interface name"},
           {"interface: can/0\nnode_id: 2", "d.yaml:1:1: interface: a network interface name"},
           {"interface: 'can 0'\nnode_id: 2", "d.yaml:1:1: interface: a network interface name"},
           {"interface: vcan0\nnode_id: 2\nbitrate: 0", "d.yaml:3:1: bitrate: must be 10000..1000000 bit/s"},
           {"interface: vcan0\nnode_id: 2\nunits: {counts_per_rev: 1.0e200, gear_ratio: 1.0e200}",
            "units.gear_ratio: counts_per_rev x gear_ratio must be a finite, non-zero count"},
           {"interface: vcan0\nnode_id: 2\nunits: {counts_per_rev: 1.0e-200, gear_ratio: 1.0e-200}",
            "units.gear_ratio: counts_per_rev x gear_ratio must be a finite, non-zero count"},
           {"interface: vcan0\nnode_id: 2\nsync_period_us: 200",
            "d.yaml:3:1: sync_period_us: must be >= 285 us, the time RPDO1 + SYNC + TPDO1 take at 1000000 bit/s"},
           {"interface: vcan0\nnode_id: 2\nbitrate: 125000\nsync_period_us: 1000", "sync_period_us: must be >= 2280 us"},
           {"interface: vcan0\nnode_id: 2\nbitrate: -500000", "d.yaml:3:1: bitrate: must be 10000..1000000 bit/s"},
           {"interface: vcan0\nnode_id: 2\ntimeouts: {sdo_ms: 100000000000000000}",
            "d.yaml:3:12: timeouts.sdo_ms: must be 1..600000 ms, got '100000000000000000'"},
           {"interface: vcan0\nnode_id: 2\ntimeouts: {boot_ms: 100000000000000000}",
            "d.yaml:3:12: timeouts.boot_ms: must be 1..600000 ms, got '100000000000000000'"}}) {
    try {
      Cia402Config::from_yaml(cfg::Node::load_string(text + "\n", "d.yaml"));
      ADD_FAILURE() << "accepted: " << text;
    } catch (const cfg::Error& e) {
      EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << e.what();
    }
  }
  try {
    Cia402EmulatorConfig::from_yaml(cfg::Node::load_string("interface: averyveryverylongcan0\nnode_id: 2\n", "e.yaml"));
    ADD_FAILURE() << "the emulator accepted a 21 character interface name";
  } catch (const cfg::Error& e) {
    EXPECT_NE(std::string(e.what()).find("e.yaml:1:1: interface: a network interface name"), std::string::npos) << e.what();
  }
  // pdos was cast to int before its range check: 4294967297 became 1 and passed.
  try {
    Cia402EmulatorConfig::from_yaml(cfg::Node::load_string("node_id: 2\npdos: 4294967297\n", "e.yaml"));
    ADD_FAILURE() << "the emulator accepted 4294967297 PDOs";
  } catch (const cfg::Error& e) {
    EXPECT_NE(std::string(e.what()).find("e.yaml:2:1: pdos: must be 1..4, got '4294967297'"), std::string::npos) << e.what();
  }
  // The largest values that fit are taken.
  const auto ok = Cia402Config::from_yaml(cfg::Node::load_string(
      "interface: can-fifteen-chr\nnode_id: 2\nbitrate: 10000\nheartbeat: {producer_ms: 65535, timeout_ms: 600000}\n", "d.yaml"));
  EXPECT_EQ(ok.interface, "can-fifteen-chr");
  EXPECT_EQ(ok.heartbeat_producer.count(), 65535);
}

// The bench's own heartbeat and what the drive does when it stops (issue 38 item 10).
TEST(Cia402Config, BenchHeartbeatKeysAndTheirErrors) {
  const auto c = Cia402Config::from_yaml(cfg::Node::load_string(
      "interface: vcan0\nnode_id: 2\nbench_heartbeat: {node_id: 100, producer_ms: 20, drive_timeout_ms: 150, on_loss: "
      "disable_voltage, required: false}\n",
      "d.yaml"));
  EXPECT_EQ(c.bench_heartbeat.node_id, 100);
  EXPECT_EQ(c.bench_heartbeat.producer.count(), 20);
  EXPECT_EQ(c.bench_heartbeat.drive_timeout.count(), 150);
  EXPECT_EQ(c.bench_heartbeat.on_loss, 2);
  EXPECT_FALSE(c.bench_heartbeat.required);
  const auto d = Cia402Config::from_yaml(cfg::Node::load_string("interface: vcan0\nnode_id: 2\n", "d.yaml"));
  EXPECT_EQ(d.bench_heartbeat.node_id, 127);
  EXPECT_EQ(d.bench_heartbeat.on_loss, 3);  // quick stop
  EXPECT_TRUE(d.bench_heartbeat.required);
  for (const auto& [text, want] : std::vector<std::pair<std::string, std::string>>{
           {"node_id: 2\nbench_heartbeat: {node_id: 2}",
            "d.yaml:3:19: bench_heartbeat.node_id: must not be the drive's node id, got '2'"},
           {"node_id: 127", "d.yaml:2:1: node_id: is the bench's default node id (127)"},
           {"node_id: 2\nbench_heartbeat: {producer_ms: 100, drive_timeout_ms: 100}",
            "bench_heartbeat.drive_timeout_ms: drive_timeout_ms (100) must be longer than producer_ms (100)"},
           {"node_id: 2\nbench_heartbeat: {drive_timeout_ms: 65536}", "bench_heartbeat.drive_timeout_ms: must be 1..65535 ms"},
           {"node_id: 2\nbench_heartbeat: {on_loss: nothing}",
            "bench_heartbeat.on_loss: must be quick_stop, disable_voltage or fault"}}) {
    try {
      Cia402Config::from_yaml(cfg::Node::load_string("interface: vcan0\n" + text + "\n", "d.yaml"));
      ADD_FAILURE() << text;
    } catch (const cfg::Error& e) {
      EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << e.what();
    }
  }
}

TEST(Cia402Config, LimitsInDegreesAndTheirErrors) {
  const auto ok = cfg::Node::load_string(
      "interface: vcan0\nnode_id: 2\nlimits: {following_error_window_deg: 0.5, following_error_timeout_ms: 20,\n"
      "  max_profile_velocity_deg_s: 3600, quick_stop_deceleration_deg_s2: 36000}\n",
      "d.yaml");
  const auto c = Cia402Config::from_yaml(ok);
  EXPECT_NEAR(c.limits.following_error_window_rad, 0.5 * 3.14159265358979 / 180, 1e-12);
  EXPECT_EQ(c.limits.following_error_timeout, std::chrono::milliseconds(20));
  EXPECT_NEAR(c.limits.max_profile_velocity_rad_s, 20 * 3.14159265358979, 1e-9);
  EXPECT_NEAR(c.limits.quick_stop_deceleration_rad_s2, 200 * 3.14159265358979, 1e-9);
  const auto none = Cia402Config::from_yaml(cfg::Node::load_string("interface: vcan0\nnode_id: 2\n", "d.yaml"));
  EXPECT_EQ(none.limits.following_error_window_rad, 0);  // nothing written at configure
  EXPECT_LT(none.limits.following_error_timeout.count(), 0);
  for (const auto& [text, want] : std::vector<std::pair<std::string, std::string>>{
           {"limits: {following_error_timeout_ms: 70000}", "d.yaml:3:10: limits.following_error_timeout_ms: must be 0..65535 ms"},
           {"limits: {following_error_window_deg: -1}", "d.yaml:3:10: limits.following_error_window_deg: must be > 0"},
           {"limits: {following_error_window: 1}", "did you mean 'following_error_window_deg'"}}) {
    try {
      Cia402Config::from_yaml(cfg::Node::load_string("interface: vcan0\nnode_id: 2\n" + text + "\n", "d.yaml"));
      ADD_FAILURE() << text;
    } catch (const cfg::Error& e) {
      EXPECT_NE(std::string(e.what()).find(want), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace hil::drv
