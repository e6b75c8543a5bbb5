// The `modbus` drive client: a Modbus servo drive, TCP or RTU (ModbusDrive), `devices.drive:
// {modbus: FILE | {...}, max_age_ms: N}` in drivers/configs/modbus_drive.yaml's format. Polled on
// its own clock: fresh while younger than max_age_ms (default two polls).
#include "hil/drv/clients.hpp"
#include "hil/drv/modbus.hpp"

namespace hil::drv {
namespace {

class ModbusDriveRecipe final : public ConfigRecipe<PositionDrive, ModbusDriveConfig> {
 public:
  using ConfigRecipe::ConfigRecipe;
  std::unique_ptr<PositionDrive> make(const DeviceSetup&) const override { return std::make_unique<ModbusDrive>(config); }
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
