#include "hil/bench/campaign/run_marks.hpp"

#include <cmath>
#include <cstdio>
#include <string>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/units.hpp"

namespace hil::bench {

RunMarks marks_from_programme(const Campaign& c, std::size_t max_marks) {
  RunMarks out;
  // Breakpoints in pairs (a step is two at one time; a drift runs from one to the next).
  const auto& pts = c.gap_rad.points();
  for (std::size_t i = 0; i + 1 < pts.size() && out.marks.size() < max_marks; i += 2) {
    char deg[32];
    std::snprintf(deg, sizeof deg, "%.4g", units::rad_to_deg(pts[i + 1].value));
    out.marks.push_back({pts[i].t_s, std::nan(""), "gap " + std::string(deg) + " deg (programme)", "gap_change", "programme",
                         units::rad_to_deg(pts[i + 1].value)});
  }
  return out;
}

}  // namespace hil::bench
