// The campaign report: one self-contained report.html comparing the runs side by side with the
// paper-style figures (pressure vs reference, touch state, motor vs valve angle, gap estimate vs
// true gap) and a table of the summary metrics.
#pragma once

#include <filesystem>
#include <vector>

#include "hil/bench/campaign.hpp"
#include "hil/bench/sim.hpp"

namespace hil::bench {

void write_sim_report(const Campaign& c, const std::vector<RunOutcome>& runs, const std::filesystem::path& file);

}  // namespace hil::bench
