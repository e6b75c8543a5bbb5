// The `modbus` sensor client: a Modbus pressure transducer, TCP or RTU (ModbusTransducer),
// `devices.transducer: {modbus: FILE | {...}, max_age_ms: N}` in
// drivers/configs/modbus_transducer.yaml's format. Polled: fresh while younger than max_age_ms
// (default two polls).
#include "hil/drv/clients.hpp"
#include "hil/drv/modbus.hpp"

namespace hil::drv {
namespace {

class ModbusTransducerRecipe final : public ConfigRecipe<PressureSensor, ModbusTransducerConfig> {
 public:
  using ConfigRecipe::ConfigRecipe;
  std::unique_ptr<PressureSensor> make(const DeviceSetup&) const override { return std::make_unique<ModbusTransducer>(config); }
};

std::shared_ptr<const SensorRecipe> load(const DeviceNodes& n) {
  n.device.allow_keys({"modbus", "max_age_ms"});
  auto recipe = std::make_shared<ModbusTransducerRecipe>(client_config<ModbusTransducerConfig>(n.client));
  recipe->max_age = poll_max_age(n.device, recipe->config.link.poll_period);
  return recipe;
}

}  // namespace
}  // namespace hil::drv

HIL_REGISTER_SENSOR_CLIENT(modbus, {.doc = "a Modbus pressure transducer", .load = &hil::drv::load})
