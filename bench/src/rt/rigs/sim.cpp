// The `sim` rig kind: the simulated rig (sim_rig.hpp; the offline simulation runs it too, so it
// lives with the loop in hil_bench) and its registration.
#include "hil/bench/rt/rig_registry.hpp"
#include "hil/bench/rt/sim_rig.hpp"

namespace {
std::unique_ptr<hil::bench::Rig> make_sim_rig(const hil::bench::RigKindInfo&, const hil::bench::RigConfig&,
                                              const hil::drv::CanTransportFactory&) {
  return std::make_unique<hil::bench::SimRig>();
}
}  // namespace

HIL_REGISTER_RIG_KIND(sim, {.doc = "the campaign's plant, stepped in lock-step with the loop (any speed, faults on purpose)",
                            .capabilities = {.simulated = true, .programmable_gap = true, .knows_truth = true},
                            .devices = {},
                            .make = &make_sim_rig})
