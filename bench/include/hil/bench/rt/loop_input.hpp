// What a run gives the loop (RunLoop) and the rig (RigSetup): the programme every run of a
// campaign shares (the simulated plant, the period and duration, the seed, the reference and gap
// schedules) and the run itself (its controller's parameters). rt/ owns these types so that it
// needs nothing from campaign/: a campaign (campaign/campaign.hpp) is a LoopProgramme with its
// name, files and checks, and its runs are RunSpecs.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "hil/bench/rt/schedule.hpp"
#include "hil/ctl/controller.hpp"
#include "hil/plant/plant.hpp"

namespace hil::bench {

struct LoopProgramme {
  std::shared_ptr<const plant::Plant> plant;  // the simulated truth (simulated and hybrid rigs)
  double duration_s = 0;
  double period_s = 0;  // the control period dT (loop time, not wall time)
  std::uint64_t seed = 1;
  Schedule reference_pa;
  Schedule gap_rad;
};

struct RunSpec {
  std::string name;
  ctl::ControllerParams controller;  // complete, validated
  int initial_touch = +1;            // the plant starts in positive contact
};

}  // namespace hil::bench
