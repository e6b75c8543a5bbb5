// The JUnit XML of a campaign run by the campaign runner: `hilbench ctl start --junit FILE` (the
// server's status, last) and `hilbench run --junit FILE` (the runner's own status, the same
// object): the runs' checks as the runner's RunChecks made them on the rig, through the same
// writer as `hilbench sim --junit` (junit_xml: a testsuite per campaign, a testcase per run and
// check; a run that did not complete, or never ran, an error with its reason).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace hil::bench {

// --junit FILE, checked before the campaign starts (hil/output_path.hpp): a new file or JUnit XML
// the tool wrote, never one of `inputs`, a device, a FIFO or a link. Throws std::invalid_argument.
void check_junit_output(const std::string& file, const std::vector<std::filesystem::path>& inputs);

// The failed checks of `last` (the status's "last" object, a finished campaign); writes FILE
// (atomically, its folder made). Throws std::runtime_error naming what in `last` is not as the
// runner writes it.
long write_served_junit(const nlohmann::json& last, const std::string& file);

}  // namespace hil::bench
