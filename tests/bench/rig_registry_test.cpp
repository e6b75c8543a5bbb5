// Rig kinds by name (the registry, linked into this static test binary like into hilbench), and
// a rig composed from parts: test doubles of a position drive and a pressure sensor
// (tests/support/test_parts.hpp) behind the loop's interface, with no bus, thread or emulator.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "hil/bench/rt/device_rig.hpp"
#include "hil/bench/rt/rig_config.hpp"
#include "hil/bench/rt/rig_registry.hpp"
#include "hil/bench/rt/sim_rig.hpp"
#include "loop_fixture.hpp"
#include "test_parts.hpp"

using namespace hil;
using namespace hil::test;

namespace {

const std::string kSafety = "safety: {cmd_min_deg: -5, cmd_max_deg: 35, rate_limit_deg_s: 100, p_max_mpa: 2.5, p_min_mpa: 0.2}\n";

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(RigRegistry, ListsTheBuiltInKindsWithTheirCapabilities) {
  // Registered from their own files' static initialisers: present although nothing in this
  // binary names them, so the whole-archive link works.
  const std::vector<std::string> names = bench::rig_kind_names();
  for (const char* kind : {"sim", "can", "modbus", "hybrid"}) {
    EXPECT_NE(std::find(names.begin(), names.end(), kind), names.end()) << kind;
  }
  EXPECT_TRUE(std::is_sorted(names.begin(), names.end()));

  struct Want {
    const char* kind;
    bool simulated, programmable_gap, knows_truth;
    bool drive;
    const char* drive_client;  // "": any registered drive client
    bool transducer;
  };
  for (const Want& w :
       {Want{"sim", true, true, true, false, "", false}, Want{"can", false, false, false, true, "cia402", true},
        Want{"modbus", false, false, false, true, "modbus", true}, Want{"hybrid", false, true, true, true, "", false}}) {
    const bench::RigKindInfo* k = bench::find_rig_kind(w.kind);
    ASSERT_NE(k, nullptr) << w.kind;
    EXPECT_EQ(k->kind, w.kind);
    EXPECT_FALSE(k->doc.empty()) << w.kind;
    EXPECT_EQ(k->capabilities.simulated, w.simulated) << w.kind;
    EXPECT_EQ(k->capabilities.programmable_gap, w.programmable_gap) << w.kind;
    EXPECT_EQ(k->capabilities.knows_truth, w.knows_truth) << w.kind;
    EXPECT_EQ(k->devices.drive, w.drive) << w.kind;
    EXPECT_EQ(k->devices.drive_client, w.drive_client) << w.kind;
    EXPECT_EQ(k->devices.transducer, w.transducer) << w.kind;
    ASSERT_NE(k->make, nullptr) << w.kind;
  }
  EXPECT_EQ(bench::find_rig_kind("nope"), nullptr);

  // The rig a kind makes answers as the kind declares (the device kinds: rigs_test.cpp).
  const auto sim = bench::make_rig(bench::load_rig_config(source_path("configs/rigs/sim.yaml")));
  ASSERT_NE(dynamic_cast<bench::SimRig*>(sim.get()), nullptr);
  EXPECT_EQ(sim->kind(), "sim");
  const bench::RigCapabilities& declared = bench::find_rig_kind("sim")->capabilities;
  EXPECT_EQ(sim->simulated(), declared.simulated);
  EXPECT_EQ(sim->programmable_gap(), declared.programmable_gap);
  EXPECT_EQ(sim->knows_truth(), declared.knows_truth);
}

TEST(RigRegistry, UnknownKindListsTheKnownKindsAndSuggestsTheClosest) {
  const std::string text = bench::unknown_rig_kind_text("hybird");
  EXPECT_NE(text.find("unknown rig kind 'hybird'"), std::string::npos) << text;
  EXPECT_NE(text.find("(did you mean 'hybrid'?)"), std::string::npos) << text;
  EXPECT_NE(text.find("this build knows: can, hybrid, modbus, sim"), std::string::npos) << text;
  EXPECT_EQ(bench::unknown_rig_kind_text("qqqqqqqqqq").find("did you mean"), std::string::npos);

  // In a rig file: located at the key.
  TempDir dir;
  std::string e = error_of([&] { bench::load_rig_config(dir.write("rigs/bad.yaml", "kind: modbsu\n" + kSafety)); });
  EXPECT_NE(e.find("bad.yaml:1:"), std::string::npos) << e;
  EXPECT_NE(e.find("kind"), std::string::npos) << e;
  EXPECT_NE(e.find("did you mean 'modbus'"), std::string::npos) << e;
  EXPECT_NE(e.find("this build knows: can, hybrid, modbus, sim"), std::string::npos) << e;

  // make_rig of a configuration that did not come through the file check names the file too.
  bench::RigConfig rc;
  rc.file = "rigs/x.yaml";
  rc.kind = "smi";
  e = error_of([&] { bench::make_rig(rc); });
  EXPECT_NE(e.find("rigs/x.yaml: unknown rig kind 'smi' (did you mean 'sim'?)"), std::string::npos) << e;
}

namespace {

// A rig kind for the composed rigs below, declared as a kind's file would.
bench::RigKindInfo parts_kind(bool simulated_chamber) {
  return {.kind = "parts",
          .doc = "test doubles",
          .capabilities = bench::capabilities_of({.drive = true, .transducer = !simulated_chamber}),
          .devices = {.drive = true, .transducer = !simulated_chamber},
          .make = nullptr};
}

bench::RigConfig parts_config() {
  bench::RigConfig rc;
  rc.name = "parts";
  rc.kind = "parts";
  rc.file = "rigs/parts.yaml";
  return rc;
}

// Where the composed rig's factories leave the parts they made, for the test to reach.
struct MadeParts {
  TestPositionDrive* drive = nullptr;
  TestPressureSensor* sensor = nullptr;
};

bench::DeviceRig::Parts test_parts(MadeParts& made, drv::FeedbackFreshness freshness, bool with_sensor, double start_rad = 0.1) {
  bench::DeviceRig::Parts p;
  p.drive = [&made, freshness, start_rad](const bench::RigSetup&) {
    auto d = std::make_unique<TestPositionDrive>(freshness, start_rad);
    made.drive = d.get();
    return d;
  };
  p.drive_max_age = std::chrono::milliseconds(40);
  if (with_sensor) {
    p.pressure_sensor = [&made](const bench::RigSetup&) {
      auto s = std::make_unique<TestPressureSensor>(1.5e6);
      made.sensor = s.get();
      return s;
    };
    p.sensor_max_age = std::chrono::milliseconds(10);
  }
  return p;
}

}  // namespace

TEST(ComposedRig, ReadsAndWritesThroughAPositionDriveAndAPressureSensor) {
  MadeParts made;
  bench::DeviceRig rig(parts_config(), parts_kind(false), test_parts(made, drv::FeedbackFreshness::polled, true));
  EXPECT_EQ(rig.kind(), "parts");
  EXPECT_FALSE(rig.simulated() || rig.programmable_gap() || rig.knows_truth());
  EXPECT_EQ(made.drive, nullptr);  // nothing made before configure
  bench::RigReading rd;
  EXPECT_EQ(rig.read(Clock::now(), 1ms, rd), bench::RigStatus::fault);
  EXPECT_NE(rig.health().last_error_text().find("parts rig: not configured"), std::string_view::npos);

  rig.configure({nullptr, 1e-3, bench::kNaN, bench::kNaN});
  ASSERT_NE(made.drive, nullptr);
  ASSERT_NE(made.sensor, nullptr);
  EXPECT_EQ(made.drive->configures, 1);
  EXPECT_EQ(made.sensor->configures, 1);
  rig.activate();
  EXPECT_EQ(made.drive->activations, 1);

  // The loop's interface, read then write, as every period.
  auto now = Clock::now();
  ASSERT_EQ(rig.read(now, 1ms, rd), bench::RigStatus::ok) << rig.health().last_error_text();
  EXPECT_DOUBLE_EQ(rd.theta_motor_rad, 0.1);
  EXPECT_DOUBLE_EQ(rd.p_meas_pa, 1.5e6);
  EXPECT_TRUE(std::isnan(rd.theta_valve_rad) && std::isnan(rd.p_chamber_pa));  // no truth from hardware
  EXPECT_EQ(rig.write(now, 1ms, {0.25, true, bench::kNaN}), bench::RigStatus::ok);
  EXPECT_DOUBLE_EQ(made.drive->last_command.target_position_rad, 0.25);  // no offset without a simulated chamber
  EXPECT_TRUE(made.drive->last_command.enable);
  made.sensor->set_pressure(1.6e6);
  now = Clock::now();
  ASSERT_EQ(rig.read(now, 1ms, rd), bench::RigStatus::ok) << rig.health().last_error_text();
  EXPECT_DOUBLE_EQ(rd.theta_motor_rad, 0.25);
  EXPECT_DOUBLE_EQ(rd.p_meas_pa, 1.6e6);
  bench::RigHealth h = rig.health();
  EXPECT_TRUE(h.connected);
  EXPECT_FALSE(h.fault);
  EXPECT_EQ(h.reads, 2u);  // counted from configure
  EXPECT_EQ(h.fault_reads, 0u);

  // A sensor reading older than its limit is stale, with the sensor's age and limit in the text;
  // the drive's feedback, as old, is still within its own limit.
  made.drive->poll();
  made.sensor->set_pressure(1.6e6);
  EXPECT_EQ(rig.read(Clock::now() + 30ms, 1ms, rd), bench::RigStatus::stale);
  h = rig.health();
  EXPECT_EQ(h.stale_reads, 1u);
  EXPECT_NE(h.last_error_text().find("transducer: newest reading"), std::string_view::npos) << h.last_error_text();
  EXPECT_NE(h.last_error_text().find("(limit 10.0 ms)"), std::string_view::npos) << h.last_error_text();
  // ... and a drive's feedback older than its limit too, the drive named first.
  EXPECT_EQ(rig.read(Clock::now() + 50ms, 1ms, rd), bench::RigStatus::stale);
  EXPECT_NE(rig.health().last_error_text().find("drive: newest feedback"), std::string_view::npos)
      << rig.health().last_error_text();
  EXPECT_NE(rig.health().last_error_text().find("(limit 40.0 ms)"), std::string_view::npos) << rig.health().last_error_text();
  made.sensor->set_pressure(1.6e6);
  made.drive->poll();
  EXPECT_EQ(rig.read(Clock::now(), 1ms, rd), bench::RigStatus::ok);
  EXPECT_EQ(rig.health().last_error_text(), "");

  // A part's fault is the rig's, in the part's own words.
  made.sensor->raise_fault("pressure out of range");
  EXPECT_EQ(rig.read(Clock::now(), 1ms, rd), bench::RigStatus::fault);
  EXPECT_EQ(rig.health().last_error_text(), "transducer: pressure out of range");
  made.drive->raise_fault("following error");
  EXPECT_EQ(rig.read(Clock::now(), 1ms, rd), bench::RigStatus::fault);
  EXPECT_TRUE(rig.health().fault);
  EXPECT_EQ(rig.health().last_error_text(), "drive: following error");  // the drive first

  rig.deactivate();
  // Asked also of a drive that reads as off: its feedback may be stale (a CAN drive out of NMT
  // operational sends no TPDO), and the client's own switch-off reads the state back.
  EXPECT_EQ(made.drive->deactivations, 1);
  EXPECT_EQ(rig.write(Clock::now(), 1ms, {0.0, true, bench::kNaN}), bench::RigStatus::fault);
}

// A drive that answers each write: fresh only with a reply newer than the last write, whatever its
// age; stale otherwise, in the drive's own words.
TEST(ComposedRig, ADriveThatAnswersEachWriteIsStaleWithoutAReply) {
  MadeParts made;
  bench::DeviceRig::Parts parts = test_parts(made, drv::FeedbackFreshness::reply_to_each_write, true);
  parts.sensor_max_age = std::chrono::seconds(10);  // only the drive's freshness is at stake here
  bench::DeviceRig rig(parts_config(), parts_kind(false), std::move(parts));
  rig.configure({nullptr, 1e-3, bench::kNaN, bench::kNaN});
  rig.activate();
  bench::RigReading rd;
  ASSERT_EQ(rig.read(Clock::now(), 1ms, rd), bench::RigStatus::ok);
  rig.write(Clock::now(), 1ms, {0.2, true, bench::kNaN});
  made.sensor->set_pressure(1.5e6);
  EXPECT_EQ(rig.read(Clock::now() + 500ms, 1ms, rd), bench::RigStatus::ok) << "old, but a reply to the last write";
  made.drive->set_silent(true);
  rig.write(Clock::now(), 1ms, {0.3, true, bench::kNaN});
  made.sensor->set_pressure(1.5e6);
  EXPECT_EQ(rig.read(Clock::now(), 1ms, rd), bench::RigStatus::stale);
  EXPECT_DOUBLE_EQ(rd.theta_motor_rad, 0.2);  // the newest it has
  EXPECT_NE(rig.health().last_error_text().find("drive: no test reply since the last write (newest "), std::string_view::npos)
      << rig.health().last_error_text();
  made.drive->set_silent(false);
  rig.write(Clock::now(), 1ms, {0.3, true, bench::kNaN});
  EXPECT_EQ(rig.read(Clock::now(), 1ms, rd), bench::RigStatus::ok);
  rig.deactivate();
  EXPECT_EQ(made.drive->deactivations, 1);
}

// activate() waits (up to 5 s) for a fresh reading of every part once the drive is enabled; an
// operator's abort did not end that wait. Here the transducer's only reading is from configure()
// (older than its 10 ms limit): the abort ends the wait within a poll, and the drive goes off.
TEST(ComposedRig, AnAbortEndsActivatesWaitForAFreshReading) {
  MadeParts made;
  bench::DeviceRig rig(parts_config(), parts_kind(false), test_parts(made, drv::FeedbackFreshness::polled, true));
  rig.configure({nullptr, 1e-3, bench::kNaN, bench::kNaN});
  std::this_thread::sleep_for(20ms);  // the configure() reading is now stale, and none comes after
  std::thread canceller([&] {
    std::this_thread::sleep_for(200ms);
    rig.cancel_setup();
  });
  const auto t0 = Clock::now();
  const std::string e = error_of([&] { rig.activate(); });
  const auto took = Clock::now() - t0;
  canceller.join();
  EXPECT_NE(e.find("parts rig: activate() cancelled while waiting for a fresh reading of every part"), std::string::npos) << e;
  EXPECT_LT(took, 2s);  // 200 ms and a loaded machine's slack; not the 5 s wait
  EXPECT_EQ(made.drive->activations, 1);
  rig.deactivate();  // as the runner does after a failed setup
  EXPECT_EQ(made.drive->deactivations, 1);
  // A cancelled rig is being given up: configure() again stops before the transducer's setup.
  made.sensor = nullptr;  // configure() drops the old one
  const std::string again = error_of([&] { rig.configure({nullptr, 1e-3, bench::kNaN, bench::kNaN}); });
  EXPECT_NE(again.find("parts rig: configure() cancelled before the transducer's setup"), std::string::npos) << again;
  EXPECT_EQ(made.sensor, nullptr) << "a transducer was made and set up after the cancel";
}

// A drive with the simulated valve and chamber (the hybrid composition): the pressure and the
// truth come from the campaign's plant stepped with the encoder angle, which is mapped onto the
// simulated motor's at configure (commands go out with the offset added).
TEST(ComposedRig, ADriveWithTheSimulatedChamber) {
  const bench::Campaign campaign = short_campaign(1.0);
  MadeParts made;
  const double encoder_start_rad = 0.7;  // wherever the real motor happens to stand
  bench::DeviceRig rig(parts_config(), parts_kind(true),
                       test_parts(made, drv::FeedbackFreshness::polled, false, encoder_start_rad));
  EXPECT_TRUE(rig.programmable_gap() && rig.knows_truth() && !rig.simulated());
  rig.configure({&campaign, campaign.period_s, campaign.reference_pa.at(0.0), campaign.gap_rad.at(0.0)});
  EXPECT_EQ(made.sensor, nullptr);
  rig.activate();
  bench::RigReading rd;
  ASSERT_EQ(rig.read(Clock::now(), 1ms, rd), bench::RigStatus::ok) << rig.health().last_error_text();
  const double motor_sim_rad = rd.theta_motor_rad;  // the settled plant's motor, not the encoder's angle
  EXPECT_TRUE(std::isfinite(motor_sim_rad));
  EXPECT_NEAR(rd.p_meas_pa, campaign.reference_pa.at(0.0), 0.05 * campaign.reference_pa.at(0.0));
  EXPECT_TRUE(std::isfinite(rd.theta_valve_rad) && std::isfinite(rd.p_chamber_pa));
  const double offset_rad = encoder_start_rad - motor_sim_rad;
  ASSERT_EQ(rig.write(Clock::now(), 1ms, {motor_sim_rad + 0.01, true, campaign.gap_rad.at(0.0)}), bench::RigStatus::ok);
  EXPECT_NEAR(made.drive->last_command.target_position_rad, motor_sim_rad + 0.01 + offset_rad, 1e-12);
  ASSERT_EQ(rig.read(Clock::now(), 1ms, rd), bench::RigStatus::ok);
  EXPECT_NEAR(rd.theta_motor_rad, motor_sim_rad + 0.01, 1e-12);  // back in the simulation's frame
  rig.deactivate();
}

TEST(ComposedRig, DeclaredCapabilitiesMustMatchTheParts) {
  MadeParts made;
  EXPECT_THROW(bench::DeviceRig(parts_config(), parts_kind(true), test_parts(made, drv::FeedbackFreshness::polled, true)),
               std::logic_error);
  EXPECT_THROW(bench::DeviceRig(parts_config(), parts_kind(false), test_parts(made, drv::FeedbackFreshness::polled, false)),
               std::logic_error);
  bench::DeviceRig::Parts no_drive;
  const std::string e = error_of([&] { bench::DeviceRig(parts_config(), parts_kind(true), no_drive); });
  EXPECT_NE(e.find("rigs/parts.yaml: rig 'parts' has no drive"), std::string::npos) << e;
}
