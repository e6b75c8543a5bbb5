// Hand-made inputs of the checks evaluator's tests (checks_test, checks_live_test): a campaign of
// nothing but what the evaluator reads, and one telemetry record of chosen values.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/checks.hpp"
#include "hil/bench/rt/telemetry_record.hpp"
#include "hil/config.hpp"
#include "hil/units.hpp"

namespace hil::test {

// A campaign of nothing but what the evaluator reads: reversals and checks (for runs none, run).
inline bench::Campaign campaign_with(const std::string& checks_yaml, std::vector<double> reversals_s = {}) {
  bench::Campaign c;
  c.name = "hand";
  c.reversals_s = std::move(reversals_s);
  c.checks = bench::parse_checks(cfg::Node::load_string(checks_yaml, "hand.yaml"), {"none", "run"});
  return c;
}

// One period's record: the reference and the measured (= chamber) pressure, the true and
// estimated gap.
inline bench::TelemetryRecord record(double t_s, double p_ref_mpa, double p_meas_mpa, double gap_true_deg = 1,
                                     double gap_est_deg = 1) {
  bench::TelemetryRecord r;
  r.step.t_s = t_s;
  r.step.p_ref_pa = units::mpa_to_pa(p_ref_mpa);
  r.step.p_meas_pa = r.step.p_chamber_pa = units::mpa_to_pa(p_meas_mpa);
  r.step.gap_true_rad = units::deg_to_rad(gap_true_deg);
  r.step.gap_est_rad = units::deg_to_rad(gap_est_deg);
  return r;
}

}  // namespace hil::test
