// Adding a drive client is one file: this one. It defines a drive client (a fake servo that is at
// its target at once and answers each write), registers it by its rig-file key `fake` as the
// drivers' own clients register (drivers/src/clients/), and runs a campaign on it through the
// hybrid rig the way `hilbench serve` runs one (CampaignRunner), with no other file of the
// project told about it. What is checked is behaviour: the drive received every commanded
// position (in its own frame: the rig's offset added), the simulated motor follows it a period
// later, and the run ends with its normal records.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <memory>
#include <vector>

#include "hil/csv_reader.hpp"
#include "hil/drv/clients.hpp"
#include "hil/units.hpp"
#include "hil_chain.hpp"

using namespace hil;
using namespace hil::test;

namespace {

// What the loop sent the fake drive, kept where the test can read it after the run. Sized at
// configure (setup): the loop's write() only stores into it, so it stays real-time safe.
struct FakeLog {
  std::vector<double> targets_rad;
  std::atomic<std::size_t> writes{0};
  std::atomic<int> configures{0}, activations{0}, deactivations{0};
  double start_rad = 0;
};
FakeLog& fake_log() {
  static FakeLog log;
  return log;
}

class FakeDrive final : public drv::PositionDrive {
 public:
  FakeDrive(double start_rad, std::size_t capacity) {
    fb_.position_rad = start_rad;
    fake_log().targets_rad.assign(capacity, std::nan(""));
    fake_log().writes = 0;
  }
  void configure() override {
    ++fake_log().configures;
    reply();
  }
  void activate() override {
    ++fake_log().activations;
    fb_.enabled = true;
    reply();
  }
  void deactivate() override {
    ++fake_log().deactivations;
    fb_.enabled = false;
    reply();
  }
  drv::DriveFeedback read(drv::Clock::time_point, drv::Clock::duration) noexcept override { return fb_; }
  void write(drv::Clock::time_point, drv::Clock::duration, const drv::DriveCommand& command) noexcept override {
    FakeLog& log = fake_log();
    const std::size_t i = log.writes.load(std::memory_order_relaxed);
    if (i < log.targets_rad.size()) log.targets_rad[i] = command.target_position_rad;
    log.writes.store(i + 1, std::memory_order_release);
    if (command.enable && std::isfinite(command.target_position_rad)) fb_.position_rad = command.target_position_rad;
    reply();
  }
  drv::DeviceHealth health() const noexcept override {
    drv::DeviceHealth h;
    h.connected = true;
    return h;
  }
  // Each write is answered at once: the feedback is fresh when it came after the last write.
  drv::FeedbackFreshness freshness() const noexcept override { return drv::FeedbackFreshness::reply_to_each_write; }

 private:
  void reply() noexcept {
    fb_.valid = true;
    fb_.rx_time = drv::Clock::now();
    ++fb_.sequence;
  }
  drv::DriveFeedback fb_{};
};

// devices.drive: {fake: {start_deg: D}}: where the fake's encoder stands at configure.
class FakeRecipe final : public drv::DriveRecipe {
 public:
  explicit FakeRecipe(double start_rad) : start_rad_(start_rad) {}
  std::unique_ptr<drv::PositionDrive> make(const drv::DeviceSetup& setup) const override {
    fake_log().start_rad = start_rad_;
    // Room for a campaign of up to 60 s at this period: the log never grows on the loop.
    return std::make_unique<FakeDrive>(start_rad_, static_cast<std::size_t>(std::lround(60.0 / setup.period_s)));
  }

 private:
  double start_rad_;
};

std::shared_ptr<const drv::DriveRecipe> load_fake(const drv::DeviceNodes& n) {
  n.device.allow_keys({"fake"});
  n.client.allow_keys({"start_deg"});
  const double start_deg = n.client.number("start_deg", 0.0);
  n.client.require(std::isfinite(start_deg) && std::abs(start_deg) <= 360, "start_deg must be within +-360");
  return std::make_shared<FakeRecipe>(units::deg_to_rad(start_deg));
}

}  // namespace

HIL_REGISTER_DRIVE_CLIENT(fake, {.doc = "a fake servo for tests", .load = &load_fake})

TEST(DriveClientPart, AFakeDriveRegisteredFromOneFileRunsACampaignThroughTheHybridRig) {
  ASSERT_NE(drv::find_drive_client("fake"), nullptr);
  // 3000 periods of 1 ms; the reference steps up at 2.5 s, so the motor is commanded to move.
  const bench::Campaign campaign = short_paper_campaign(3.0);
  Bench b;
  b.start(campaign, rig_yaml("hybrid", "    fake: {start_deg: 7.5}\n", ""));
  const json last = b.finish(60s);
  ASSERT_EQ(last["outcome"], "completed") << last.dump(2);
  EXPECT_EQ(fake_log().configures, 1);
  EXPECT_EQ(fake_log().activations, 1);
  EXPECT_EQ(fake_log().deactivations, 1);

  // The normal records: run.json, the telemetry with the truth columns (the simulated chamber),
  // one row a period, and the events.
  ASSERT_EQ(b.runs().size(), 1u);
  const RunFiles f(b.runs().back(), true);
  EXPECT_EQ(f.run["rig"]["kind"], "hybrid");
  EXPECT_EQ(f.run["outcome"], "completed");
  const std::size_t rows = f.csv.rows();
  EXPECT_EQ(rows, 3000u);
  EXPECT_FALSE(f.events.empty());

  // Every period's command reached the fake drive, in the drive's frame: what the rig sent
  // (theta_target_deg: the controller's command after the interlocks and shaping) plus one offset
  // for the whole run (the fake's start angle minus the settled plant's motor). telemetry.csv
  // holds 5 decimals of a degree: each value within half of 1e-5.
  const CsvChunk t = read_csv(f.dir / "telemetry.csv", {{"theta_target_deg", "theta_motor_deg"}, {}, "t_s"});
  const auto& target_deg = t.values[0];
  const auto& motor_deg = t.values[1];
  constexpr double kTolDeg = 1.1e-5;
  const std::size_t writes = fake_log().writes.load(std::memory_order_acquire);
  ASSERT_GE(writes, rows);
  const double offset_deg = units::rad_to_deg(fake_log().targets_rad[0]) - target_deg[0];
  // The rig mapped the fake's start onto the settled motor: the first row's motor is the plant's,
  // and the fake's start angle is that plus the offset.
  EXPECT_NEAR(motor_deg[0] + offset_deg, 7.5, kTolDeg);
  double moved_deg = 0;
  for (std::size_t i = 0; i < rows; ++i) {
    ASSERT_NEAR(units::rad_to_deg(fake_log().targets_rad[i]) - target_deg[i], offset_deg, 2 * kTolDeg) << "row " << i;
    // The fake is at its target at once, and the rig reads it the next period: the simulated
    // motor is the previous period's target.
    if (i > 0) {
      ASSERT_NEAR(motor_deg[i], target_deg[i - 1], 2 * kTolDeg) << "row " << i;
    }
    moved_deg = std::max(moved_deg, std::abs(target_deg[i] - target_deg[0]));
  }
  EXPECT_GT(moved_deg, 0.01);  // the controller did command a move: the check above is not of a constant
}

TEST(DriveClientPart, ARigFileNamingAnUnknownClientIsRefusedWithTheKnownOnes) {
  TempDir dir;
  try {
    bench::load_rig_config(dir.write("rigs/bad.yaml", rig_yaml("hybrid", "    fakee: {start_deg: 1}\n", "")));
    ADD_FAILURE() << "loaded";
  } catch (const std::exception& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("bad.yaml:5:"), std::string::npos) << what;
    EXPECT_NE(what.find("devices.drive"), std::string::npos) << what;
    EXPECT_NE(what.find("cia402, fake, modbus"), std::string::npos) << what;
    EXPECT_NE(what.find("did you mean 'fake'"), std::string::npos) << what;
  }
  // The can rig takes the CiA 402 client only, whatever else is registered.
  try {
    bench::load_rig_config(dir.write("rigs/can.yaml", rig_yaml("can", "    fake: {start_deg: 1}\n", "")));
    ADD_FAILURE() << "loaded";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("the can rig needs a CiA 402 drive on CAN (drive: {cia402: ...})"), std::string::npos)
        << e.what();
  }
}
