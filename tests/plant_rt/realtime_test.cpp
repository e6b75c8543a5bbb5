// The plant's step is on the real-time path: it must not allocate.
#include <gtest/gtest.h>

#include "alloc_counter.hpp"
#include "hil/config.hpp"
#include "hil/plant/plant.hpp"
#include "hil/plant/registry.hpp"
#include "temp_file.hpp"

using namespace hil::plant;

TEST(PlantRealtime, StepDoesNotAllocateWithEveryEffect) {
  Plant plant = Plant::load(hil::test::source_path("configs/plant/nominal.yaml"));
  for (const char* extra :
       {"transport_delay:\n  delay_s: 0.02\n", "sensor_lag:\n  time_constant_s: 0.01\n", "sensor_bias:\n  offset_kpa: 3\n",
        "valve_offset:\n  offset_deg: 0.3\n", "throat_erosion:\n  rate_mm2_per_s: 0.1\n", "backlash_change:\n  gap_deg: 1.1\n"}) {
    const auto node = hil::cfg::Node::load_string(extra, "extra.yaml");
    const auto [name, block] = node.entries().front();
    plant = plant.with(find_effect(name)->from_yaml(block));
  }
  PlantState st = plant.make_state(5);
  plant.settle(st, 1.0e6);
  const long before = hil::test::allocations();
  for (int k = 0; k < 20000; ++k) plant.step(st, {0.2 + 1e-5 * k, kNaN, kNaN}, 1e-3);
  EXPECT_EQ(hil::test::allocations() - before, 0);
}
