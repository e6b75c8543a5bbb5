// `hilbench ctl start --junit FILE` against the real `hilbench serve` on the simulated rig: the
// served campaign's verdicts as JUnit XML, read by a real consumer (Debian's python3-junitparser)
// with the counts run.json has, and exit 3 for a check set to fail (the CI job's contract; the
// hybrid rig over vcan0 does the same in tests/hil/vcan_rigs_test.cpp).
#include <gtest/gtest.h>

#include <fstream>

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
