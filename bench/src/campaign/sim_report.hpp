// The campaign report: one self-contained report.html comparing the runs side by side with the
// paper-style figures (pressure vs reference, touch state, motor vs valve angle, gap estimate vs
// true gap) and a table of the summary metrics.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/sim.hpp"

namespace hil::bench {

// `origin` heads the page ("hilbench sim", "hilbench report"); `note`, when set, is a paragraph
// under the campaign's description (where recorded runs came from and how they ended).
void write_sim_report(const Campaign& c, const std::vector<RunOutcome>& runs, const std::filesystem::path& file,
                      const std::string& origin = "hilbench sim", const std::string& note = "");

}  // namespace hil::bench
