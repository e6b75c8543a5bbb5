// `hilbench ctl start --junit FILE`: a served campaign's verdicts (the status's last.runs[].checks,
// as the server's RunChecks made them on the rig) as JUnit XML, through the same writer as
// `hilbench sim --junit` (junit_xml: a testsuite per campaign, a testcase per run and check).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace hil::bench {

// The failed checks of `last` (the status's "last" object, a finished campaign); writes FILE
// (atomically, its folder made). Throws std::runtime_error naming what in `last` is not as the
// server writes it.
long write_served_junit(const nlohmann::json& last, const std::string& file);

}  // namespace hil::bench
