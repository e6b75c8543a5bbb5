#include "ctl_junit.hpp"

#include <cmath>
#include <filesystem>
#include <stdexcept>

#include "hil/bench/campaign/checks.hpp"
#include "hil/line_file.hpp"
#include "hil/output_path.hpp"

namespace hil::bench {
namespace {

using json = nlohmann::json;

// A result as CheckResult::to_json wrote it; NaN/absent where the server wrote null.
CheckResult result_from(const json& j, const std::string& run) {
  CheckResult r;
  r.check = j.value("check", "?");
  r.run = j.value("run", run);
  const std::string v = j.value("verdict", "");
  if (v != "pass" && v != "fail" && v != "skipped") throw std::runtime_error("check '" + r.check + "': no verdict '" + v + "'");
  r.verdict = v == "pass" ? Verdict::pass : v == "fail" ? Verdict::fail : Verdict::skipped;
  const auto number = [&](const char* key) {
    return j.contains(key) && j[key].is_number() ? j[key].get<double>() : std::nan("");
  };
  r.value = number("value");
  r.at_s = number("at_s");
  if (j.contains("min") && j["min"].is_number()) r.min = j["min"].get<double>();
  if (j.contains("max") && j["max"].is_number()) r.max = j["max"].get<double>();
  if (j.contains("samples") && j["samples"].is_number_integer()) r.samples = j["samples"].get<long>();
  r.message = j.value("message", "");
  return r;
}

// A run of last.runs[]: its checks, its outcome and its wall time.
JunitRun run_from(const json& run) {
  JunitRun jr;
  jr.name = run.value("run", "?");
  if (run.contains("checks") && run["checks"].is_object()) {
    for (const auto& c : run["checks"].value("results", json::array())) jr.results.push_back(result_from(c, jr.name));
  }
  jr.outcome = run.value("outcome", "error");
  if (run.contains("reason") && run["reason"].is_string()) jr.reason = run["reason"].get<std::string>();
  if (run.contains("wall_s") && run["wall_s"].is_number()) jr.wall_s = run["wall_s"].get<double>();
  return jr;
}

}  // namespace

void check_junit_output(const std::string& file, const std::vector<std::filesystem::path>& inputs) {
  check_output_file("--junit", file, inputs, "the JUnit XML", kJunitSignature);
}

long write_served_junit(const json& last, const std::string& file) {
  if (!last.is_object()) throw std::runtime_error("the server has no finished campaign to report");
  JunitSuite suite;
  suite.campaign = last.value("campaign", "?");
  long failed = 0;
  for (const auto& run : last.value("runs", json::array())) {
    suite.runs.push_back(run_from(run));
    for (const auto& r : suite.runs.back().results) failed += r.verdict == Verdict::fail ? 1 : 0;
    suite.wall_s += suite.runs.back().wall_s;
  }
  // The runs a campaign that ended early never ran: errors with the campaign's reason.
  const std::string why = "the campaign ended " + last.value("outcome", std::string("early")) + " before it" +
                          (last.contains("reason") && last["reason"].is_string() ? ": " + last["reason"].get<std::string>() : "");
  const json not_run = last.value("runs_not_run", json::array());
  for (const auto& name : not_run)
    suite.runs.push_back({name.is_string() ? name.get<std::string>() : "?", 0, {}, "not run", why});
  const long unnamed = last.value("runs_skipped", 0L) - static_cast<long>(not_run.size());
  for (long i = 0; i < unnamed; ++i) suite.runs.push_back({"not run " + std::to_string(i + 1), 0, {}, "not run", why});
  const std::filesystem::path path(file);
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
  replace_file(path, junit_xml({suite}));
  return failed;
}

}  // namespace hil::bench
