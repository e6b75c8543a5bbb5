// The `cia402` drive client: a CiA 402 servo on CAN (Cia402Drive), `devices.drive: {cia402: FILE
// | {...}}` in drivers/configs/cia402_drive.yaml's format. Its feedback is fresh when a TPDO
// answered the SYNC of the loop's last write, so it takes no max_age_ms.
#include "hil/drv/cia402_drive.hpp"
#include "hil/drv/clients.hpp"

#include <algorithm>
#include <cmath>

namespace hil::drv {
namespace {

class Cia402Recipe final : public ConfigRecipe<PositionDrive, Cia402Config> {
 public:
  using ConfigRecipe::ConfigRecipe;
  std::unique_ptr<PositionDrive> make(const DeviceSetup& setup) const override {
    // One SYNC per period, sent right after the loop's command: the TPDO that answers it is the
    // next period's fresh feedback. The client's timer only keeps SYNC going while no loop runs.
    Cia402Config run = config;
    run.sync_source = Cia402Config::SyncSource::loop;
    // The campaign's period as it is (bent into 100 us..100 ms without a word, it would tell
    // the drive a wrong interpolation period): one the bus cannot carry fails here, named.
    run.sync_period = std::chrono::microseconds(std::lround(setup.period_s * 1e6));
    // The loop is hung when it misses no less than the drive's own allowance for a silent bench
    // (0x1016's time) and the rig's watchdog: a host late by less is the drive's tolerance too.
    const auto watchdog = std::chrono::milliseconds(std::lround(std::ceil(setup.watchdog_s * 1e3)));
    run.loop_hang_bound = std::max(watchdog, run.bench_heartbeat.drive_timeout);
    return std::make_unique<Cia402Drive>(std::move(run), setup.can_transport);
  }
};

std::shared_ptr<const DriveRecipe> load(const DeviceNodes& n) {
  if (const auto age = n.device.find("max_age_ms")) {
    age->fail("a CAN drive's feedback is stale when no TPDO arrived since the last SYNC; no age limit to set");
  }
  n.device.allow_keys({"cia402"});
  auto recipe = std::make_shared<Cia402Recipe>(client_config<Cia402Config>(n.client));
  // The fastest this rig moves the target: configure() and the probe check the drive's following
  // error window against it (following_window_problem).
  recipe->config.target_velocity_rad_s = n.target_velocity_rad_s;
  return recipe;
}

}  // namespace
}  // namespace hil::drv

HIL_REGISTER_DRIVE_CLIENT(cia402, {.doc = "a CiA 402 drive on CAN", .load = &hil::drv::load})
