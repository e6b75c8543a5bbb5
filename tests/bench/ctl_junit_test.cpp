// `hilbench ctl start --junit FILE` against the real `hilbench serve` on the simulated rig: the
// served campaign's verdicts as JUnit XML, read by a real consumer (Debian's python3-junitparser)
// with the counts run.json has, and exit 3 for a check set to fail (the CI job's contract; the
// hybrid rig over vcan0 does the same in tests/hil/vcan_rigs_test.cpp).
#include <gtest/gtest.h>

#include <fstream>
#include <functional>

#include "run_command.hpp"
#include "server_process.hpp"

using namespace std::chrono_literals;
using nlohmann::json;

TEST(CtlJunit, ServedVerdictsAsJunitAndACheckSetToFailExitsThree) {
  hil::test::ServerProcess server;
  const auto yaml = server.dir() / "junit_run.yaml";
  std::ofstream(yaml) << hil::test::short_campaign_yaml(2, "junit_run")
                      << "checks:\n"
                         "  - {name: set_to_fail, runs: [adaptive], metric: iae_mpa_s, max: 0}\n"
                         "  - {name: no_safe_state, signal: safe_state, max: 0}\n";
  const auto junit = server.dir() / "ci" / "junit.xml";
  const auto log = server.dir() / "ctl.log";
  const std::string url = "http://127.0.0.1:" + std::to_string(server.port());
  const pid_t pid = hil::test::spawn(
      {hil::test::hilbench_exe(), "ctl", "--server", url, "start", yaml.string(), "--speed", "4", "--junit", junit.string()},
      log);
  const auto rc = hil::test::wait_exit(pid, 60s);
  ASSERT_TRUE(rc.has_value());
  const std::string out = hil::test::slurp(log);
  EXPECT_EQ(*rc, 3) << out;
  EXPECT_NE(out.find("1 check(s) failed; JUnit XML: " + junit.string()), std::string::npos) << out;

  // What junitparser reads: a suite of the campaign, a case per run and check (none: 1, adaptive: 2).
  const auto script = server.dir() / "read.py";
  std::ofstream(script) << "import sys\n"
                           "from junitparser import JUnitXml, Failure, Skipped\n"
                           "for s in JUnitXml.fromfile(sys.argv[1]):\n"
                           "    print(s.name, s.tests, s.failures, s.skipped)\n"
                           "    for c in s:\n"
                           "        print(c.classname, c.name, ','.join(type(r).__name__ for r in c.result) or 'pass')\n";
  const auto r = hil::test::run_command("/usr/bin/python3 " + script.string() + " " + junit.string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output,
            "junit_run 3 1 0\n"
            "junit_run.none no_safe_state pass\n"
            "junit_run.adaptive set_to_fail Failure\n"
            "junit_run.adaptive no_safe_state pass\n");
  // The same verdicts as run.json (the server's RunChecks), run by run.
  long failed = 0, passed = 0;
  long runs = 0;
  for (const auto& e : std::filesystem::directory_iterator(server.runs_dir())) {
    if (!std::filesystem::exists(e.path() / "run.json")) continue;  // the server's own files beside the runs
    ++runs;
    const json run = json::parse(hil::test::slurp(e.path() / "run.json"));
    failed += run["checks"]["failed"].get<long>();
    passed += run["checks"]["passed"].get<long>();
  }
  EXPECT_EQ(runs, 2);
  EXPECT_EQ(failed, 1);
  EXPECT_EQ(passed, 2);

  // --junit needs the end of the run: with --detach it is refused before anything starts.
  const pid_t detached = hil::test::spawn(
      {hil::test::hilbench_exe(), "ctl", "--server", url, "start", yaml.string(), "--detach", "--junit", junit.string()},
      server.dir() / "detach.log");
  const auto drc = hil::test::wait_exit(detached, 20s);
  ASSERT_TRUE(drc.has_value());
  EXPECT_NE(*drc, 0);
  EXPECT_NE(hil::test::slurp(server.dir() / "detach.log").find("excludes"), std::string::npos)
      << hil::test::slurp(server.dir() / "detach.log");
}

namespace {

// The XML `ctl start --junit` wrote after `stop_with` ended the campaign; checked against the
// Jenkins xUnit schema's rules (tests/support/junit_schema_check.py).
std::string served_junit_after(const hil::test::ServerProcess& server, const std::string& rig,
                               const std::function<void(const hil::bench::ApiClient&)>& stop_with, int& rc) {
  const auto yaml = server.dir() / "long_run.yaml";
  std::ofstream(yaml) << hil::test::short_campaign_yaml(30, "long_run")
                      << "checks:\n  - {name: no_safe_state, signal: safe_state, max: 0}\n";
  const auto junit = server.dir() / "junit.xml";
  const auto log = server.dir() / "ctl.log";
  const std::string url = "http://127.0.0.1:" + std::to_string(server.port());
  const pid_t pid = hil::test::spawn(
      {hil::test::hilbench_exe(), "ctl", "--server", url, "start", yaml.string(), "--rig", rig, "--junit", junit.string()}, log);
  stop_with(server.client());
  const auto exit = hil::test::wait_exit(pid, 60s);
  EXPECT_TRUE(exit.has_value());
  rc = exit.value_or(-1);
  const auto check = hil::test::run_command(
      "/usr/bin/python3 " + hil::test::source_path("tests/support/junit_schema_check.py").string() + " " + junit.string());
  EXPECT_EQ(check.status, 0) << check.output;
  return hil::test::slurp(junit) + "\n" + hil::test::slurp(log);
}

}  // namespace

// A campaign stopped during its first run gave 2 tests, 0 failures: the stopped run and the run
// never run are errors, with their reasons, never passed or skipped.
TEST(CtlJunit, AStoppedCampaignListsItsRunsAsErrors) {
  hil::test::ServerProcess server;
  int rc = 0;
  const std::string xml = served_junit_after(
      server, "sim",
      [](const hil::bench::ApiClient& api) {
        hil::test::wait_status(
            api, [](const json& s) { return s.value("state", "") == "running"; }, 30s);
        api.post("/api/stop", json::object());
      },
      rc);
  EXPECT_NE(rc, 0) << xml;
  EXPECT_NE(xml.find("<error type=\"stopped\" message=\"run none stopped: operator stop\""), std::string::npos) << xml;
  EXPECT_NE(xml.find("classname=\"long_run.adaptive\" name=\"completed\" time=\"0.000\">\n      <error type=\"not run\""),
            std::string::npos)
      << xml;
  EXPECT_EQ(xml.find("<skipped"), std::string::npos) << xml;
  EXPECT_EQ(xml.find("errors=\"0\""), std::string::npos) << xml;
}

// A rig that cannot be set up (the CAN rig without its bus) gave 3 tests, 3 skipped.
TEST(CtlJunit, ARigErrorIsAnErrorNotASkip) {
  hil::test::ServerProcess server;
  int rc = 0;
  const std::string xml = served_junit_after(
      server, "can", [](const hil::bench::ApiClient&) {}, rc);
  EXPECT_NE(rc, 0) << xml;
  EXPECT_NE(xml.find("name=\"completed\""), std::string::npos) << xml;
  EXPECT_NE(xml.find("<error type=\""), std::string::npos) << xml;
  EXPECT_EQ(xml.find("<skipped"), std::string::npos) << xml;
  EXPECT_EQ(xml.find("errors=\"0\""), std::string::npos) << xml;
}
