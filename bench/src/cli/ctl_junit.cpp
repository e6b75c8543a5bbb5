#include "ctl_junit.hpp"

#include <cmath>
#include <filesystem>
#include <stdexcept>

#include "hil/bench/campaign/checks.hpp"
#include "hil/line_file.hpp"

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

}  // namespace

long write_served_junit(const json& last, const std::string& file) {
  if (!last.is_object()) throw std::runtime_error("the server has no finished campaign to report");
  JunitSuite suite{last.value("campaign", "?"), "", 0, {}};
  long failed = 0;
  for (const auto& run : last.value("runs", json::array())) {
    JunitRun jr{run.value("run", "?"), 0, {}};
    if (run.contains("checks") && run["checks"].is_object()) {
      for (const auto& c : run["checks"].value("results", json::array())) {
        jr.results.push_back(result_from(c, jr.name));
        failed += jr.results.back().verdict == Verdict::fail ? 1 : 0;
      }
    }
    suite.runs.push_back(std::move(jr));
  }
  const std::filesystem::path path(file);
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
  replace_file(path, junit_xml({suite}));
  return failed;
}

}  // namespace hil::bench
