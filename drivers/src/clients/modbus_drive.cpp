// The `modbus` drive client: a Modbus servo drive, TCP or RTU (ModbusDrive), `devices.drive:
// {modbus: FILE | {...}, max_age_ms: N}` in drivers/configs/modbus_drive.yaml's format. Polled on
// its own clock: fresh while younger than max_age_ms (default two polls).
#include "hil/drv/clients.hpp"

#include <algorithm>
#include <cmath>
#include "hil/drv/modbus.hpp"

namespace hil::drv {
namespace {

class ModbusDriveRecipe final : public ConfigRecipe<PositionDrive, ModbusDriveConfig> {
 public:
  using ConfigRecipe::ConfigRecipe;
  std::unique_ptr<PositionDrive> make(const DeviceSetup& setup) const override {
    // No drive-side watch of the bench here: the loop is hung past the rig's watchdog time, and
    // not before 500 ms (the CAN drives' default consumer time), so a late host is not a hang.
    ModbusDriveConfig run = config;
    run.loop_hang_bound =
        std::max(std::chrono::milliseconds(std::lround(std::ceil(setup.watchdog_s * 1e3))), std::chrono::milliseconds(500));
    return std::make_unique<ModbusDrive>(std::move(run));
  }
};

std::shared_ptr<const DriveRecipe> load(const DeviceNodes& n) {
  n.device.allow_keys({"modbus", "max_age_ms"});
  auto recipe = std::make_shared<ModbusDriveRecipe>(client_config<ModbusDriveConfig>(n.client));
  recipe->max_age = poll_max_age(n.device, recipe->config.link.poll_period);
  return recipe;
}

}  // namespace
}  // namespace hil::drv

HIL_REGISTER_DRIVE_CLIENT(modbus, {.doc = "a Modbus drive", .load = &hil::drv::load})
