// TEMPORARY: replaced by the hil::report figures once analysis/report lands on this branch.
#include "hil/bench/sim_report.hpp"

#include <fstream>

namespace hil::bench {

void write_sim_report(const Campaign& c, const std::vector<RunOutcome>& runs, const std::filesystem::path& file) {
  std::ofstream out(file);
  out << "<html><body><h1>" << c.name << "</h1><pre>";
  for (const auto& r : runs) out << r.name << "\n" << r.summary.to_json().dump(2) << "\n";
  out << "</pre></body></html>\n";
}

}  // namespace hil::bench
