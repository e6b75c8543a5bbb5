// `hilbench run` keeps every interlock of a served run, against the real binary as a user runs
// it: Ctrl-C pressed twice still ends in the safe state with the record written; a rig that
// needs an operator link is refused (only the server has one); a run list that names no run, or
// an empty or repeated name, is refused as `sim` refuses it; a run killed by -9 is marked
// interrupted by the next `hilbench run` and by `hilbench report`; its JUnit XML lists a run
// that did not complete, and the runs never run, as errors, valid by the Jenkins xUnit schema's
// rules; its events.jsonl ends with a run_end record, and no file says "hilbench serve".
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <functional>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "hil/bench/rt/run_record.hpp"
#include "support/run_command.hpp"
#include "support/temp_file.hpp"

using hil::test::hilbench;
using hil::test::run_command;
using hil::test::slurp;
using hil::test::source_path;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

namespace {

std::string q(const fs::path& p) { return "'" + p.string() + "'"; }

// Two runs of `duration_s` at 1 kHz; one check each can pass.
fs::path campaign(const hil::test::TempDir& dir, double duration_s) {
  return dir.write("long_run.yaml", "name: long_run\nplant: " + source_path("configs/plant/nominal.yaml").string() +
                                        "\nduration_s: " + std::to_string(duration_s) +
                                        "\nperiod_ms: 1\nseed: 3\nreference:\n  initial_mpa: 1.0\ngap:\n  initial_deg: 1.0\n"
                                        "runs:\n  - {name: none, compensation: none}\n"
                                        "  - {name: adaptive, compensation: adaptive}\n"
                                        "checks:\n  - {name: no_safe_state, signal: safe_state, max: 0}\n");
}

std::vector<fs::path> run_dirs(const fs::path& out) {
  std::vector<fs::path> dirs;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(out, ec))
    if (e.is_directory()) dirs.push_back(e.path());
  std::sort(dirs.begin(), dirs.end());
  return dirs;
}

// `hilbench run` in the background (its output into `log`).
pid_t spawn_run(const std::vector<std::string>& args, const fs::path& log) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd >= 0) ::dup2(fd, 1), ::dup2(fd, 2);
    const std::string exe = hilbench();
    std::vector<char*> argv{const_cast<char*>(exe.c_str()), const_cast<char*>("run")};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(exe.c_str(), argv.data());
    ::_exit(127);
  }
  return pid;
}

bool wait_for(const std::function<bool()>& ready, std::chrono::seconds limit) {
  for (const auto until = std::chrono::steady_clock::now() + limit; std::chrono::steady_clock::now() < until;) {
    if (ready()) return true;
    std::this_thread::sleep_for(2ms);
  }
  return false;
}

// The exit status (128 + the signal it died of); a process still there after `limit` is killed: a failure.
int wait_exit(pid_t pid, std::chrono::seconds limit) {
  int status = 0;
  if (!wait_for([&] { return ::waitpid(pid, &status, WNOHANG) == pid; }, limit)) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
    ADD_FAILURE() << "still running " << limit.count() << " s later";
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

// The first run's loop has started (its loop_start event is on disk).
bool loop_running(const fs::path& out) {
  const auto dirs = run_dirs(out);
  return !dirs.empty() && slurp(dirs.front() / "events.jsonl").find("\"kind\":\"loop_start\"") != std::string::npos;
}

std::vector<nlohmann::json> events(const fs::path& dir) {
  std::vector<nlohmann::json> all;
  std::istringstream in(slurp(dir / "events.jsonl"));
  for (std::string line; std::getline(in, line);) all.push_back(nlohmann::json::parse(line));
  return all;
}

std::size_t csv_rows(const fs::path& file) {
  std::istringstream in(slurp(file));
  std::size_t rows = 0;
  bool header = false;
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    if (header) ++rows;
    header = true;
  }
  return rows;
}

// The Jenkins xUnit schema's rules (tests/support/junit_schema_check.py) on FILE: "" when valid.
std::string schema_problems(const fs::path& file) {
  const auto r = run_command("/usr/bin/python3 " + q(source_path("tests/support/junit_schema_check.py")) + " " + q(file));
  return r.status == 0 ? "" : r.output;
}

struct Base {
  hil::test::TempDir dir;
  fs::path out = dir.path() / "runs";
  std::vector<std::string> args(const fs::path& file, std::vector<std::string> more = {}) const {
    std::vector<std::string> a{file.string(), "--rig",      "sim",       "--configs", source_path("configs").string(),
                               "--out",       out.string(), "--no-mlock"};
    a.insert(a.end(), more.begin(), more.end());
    return a;
  }
  std::string command(const fs::path& file, const std::string& more) const {
    std::string c = hilbench() + " run";
    for (const auto& a : args(file)) c += " " + q(a);
    return c + " " + more;
  }
};

// A second Ctrl-C 5 ms or 100 ms after the first ended the process at once (0.01 s), run.json
// still "running", no rows counted, no safe state recorded. Now the abort under way finishes:
// the safe state, the record, exit 130; and the JUnit XML lists the aborted run and the run
// never run as errors with their reasons.
TEST(RunInterlocks, ASecondCtrlCStillEndsInTheSafeStateWithTheRecord) {
  for (const auto gap : {5ms, 100ms}) {
    SCOPED_TRACE("second SIGINT after " + std::to_string(gap.count()) + " ms");
    Base b;
    const auto file = campaign(b.dir, 60);
    const auto junit = b.dir.path() / "ci" / "junit.xml";
    const pid_t pid = spawn_run(b.args(file, {"--junit", junit.string()}), b.dir.path() / "log");
    ASSERT_TRUE(wait_for([&] { return loop_running(b.out); }, 60s)) << slurp(b.dir.path() / "log");
    std::this_thread::sleep_for(200ms);  // rows on disk
    ::kill(pid, SIGINT);
    std::this_thread::sleep_for(gap);
    ::kill(pid, SIGINT);
    const int rc = wait_exit(pid, 30s);
    const std::string log = slurp(b.dir.path() / "log");
    EXPECT_EQ(rc, 128 + SIGINT) << log;
    EXPECT_NE(log.find("the abort is under way"), std::string::npos) << log;
    const auto dirs = run_dirs(b.out);
    ASSERT_EQ(dirs.size(), 1u) << "the second run never starts";
    const auto record = hil::bench::read_run_record(dirs[0]);
    EXPECT_EQ(record.outcome, hil::bench::Outcome::aborted) << record.reason.value_or("");
    EXPECT_EQ(record.reason.value_or(""), "SIGINT (hilbench run)");
    EXPECT_EQ(record.recorded_by, "hilbench run");
    ASSERT_TRUE(record.telemetry && record.telemetry->rows_written);
    EXPECT_GT(*record.telemetry->rows_written, 0u);
    EXPECT_EQ(*record.telemetry->rows_written, csv_rows(dirs[0] / "telemetry.csv"));
    const auto ev = events(dirs[0]);
    ASSERT_FALSE(ev.empty());
    EXPECT_TRUE(std::any_of(ev.begin(), ev.end(), [](const auto& e) { return e.value("kind", "") == "safe_state"; }));
    // The end record, last: how the run ended, as run.json says it.
    EXPECT_EQ(ev.back().value("kind", ""), "run_end") << ev.back().dump();
    EXPECT_EQ(ev.back().value("outcome", ""), "aborted");
    EXPECT_EQ(ev.back()["rows_written"], *record.telemetry->rows_written);

    const std::string xml = slurp(junit);
    EXPECT_EQ(schema_problems(junit), "") << xml;
    // The aborted run's "completed" and check, the run never run: none of them passes.
    std::smatch m;
    ASSERT_TRUE(std::regex_search(
        xml, m, std::regex("<testsuites name=\"hilbench\" tests=\"(\\d+)\" failures=\"(\\d+)\" errors=\"(\\d+)\"")))
        << xml;
    EXPECT_EQ(std::stoi(m[1]), 3) << xml;
    EXPECT_EQ(std::stoi(m[2]) + std::stoi(m[3]), 3) << xml;
    EXPECT_GE(std::stoi(m[3]), 2) << xml;
    EXPECT_NE(xml.find("<error type=\"aborted\" message=\"run none aborted: SIGINT (hilbench run)\""), std::string::npos) << xml;
    EXPECT_NE(xml.find("classname=\"long_run.adaptive\" name=\"completed\" time=\"0.000\">\n      <error type=\"not run\" "
                       "message=\"run adaptive not run: the campaign ended aborted before it: SIGINT (hilbench run)\""),
              std::string::npos)
        << xml;
    EXPECT_EQ(xml.find("<skipped"), std::string::npos) << xml;
  }
}

TEST(RunInterlocks, ARigThatNeedsAnOperatorLinkIsRefused) {
  Base b;
  const auto file = campaign(b.dir, 1);
  const auto rig = b.dir.write("rigs/watched.yaml",
                               slurp(source_path("configs/rigs/sim.yaml")) + "require_operator: true\noperator_timeout_s: 1\n");
  const auto r = run_command(hilbench() + " run " + q(file) + " --rig " + q(rig) + " --out " + q(b.out) + " --no-mlock");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find(rig.string() + ": require_operator: true needs an operator link"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("only `hilbench serve` has"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(b.out)) << "refused before anything is made";
}

// `--runs ''` (a script's empty variable) ran every run on the rig; so did ',', 'none,none' and
// 'adaptive,,none'. Refused as `hilbench sim` refuses them, before anything runs.
TEST(RunInterlocks, ARunListThatIsEmptyOrHasAnEmptyOrRepeatedNameIsRefused) {
  Base b;
  const auto file = campaign(b.dir, 1);
  const std::pair<std::string, std::string> cases[] = {
      {"''", "--runs '' names no run"},
      {",", "--runs ',' names no run"},
      {"none,none", "--runs names 'none' twice"},
      {"adaptive,,none", "--runs 'adaptive,,none' has an empty name between its commas"},
      {"adaptiv", "has no run 'adaptiv' (did you mean 'adaptive'?)"},
  };
  for (const auto& [runs, why] : cases) {
    const auto r = run_command(b.command(file, "--runs " + runs));
    EXPECT_EQ(r.status, 2) << runs << "\n" << r.output;
    EXPECT_NE(r.output.find(why), std::string::npos) << runs << "\n" << r.output;
    EXPECT_FALSE(fs::exists(b.out)) << runs;
  }
}

// kill -9 leaves run.json "running"; the next `hilbench report` of the run, and the next
// `hilbench run` into the folder, give it its honest end: interrupted, the rows on disk.
TEST(RunInterlocks, ARunKilledByNineIsMarkedInterruptedByTheNextReportAndRun) {
  for (const std::string next : {"report", "run"}) {
    SCOPED_TRACE(next);
    Base b;
    const auto file = campaign(b.dir, 60);
    const pid_t pid = spawn_run(b.args(file), b.dir.path() / "log");
    ASSERT_TRUE(wait_for([&] { return loop_running(b.out); }, 60s)) << slurp(b.dir.path() / "log");
    std::this_thread::sleep_for(300ms);
    ::kill(pid, SIGKILL);
    EXPECT_EQ(wait_exit(pid, 10s), 128 + SIGKILL);
    const fs::path killed = run_dirs(b.out).front();
    ASSERT_EQ(hil::bench::read_run_record(killed).outcome, hil::bench::Outcome::running);
    const auto r = next == "report" ? run_command(hilbench() + " report " + q(killed) + " --quiet")
                                    : run_command(b.command(campaign(b.dir, 0.2), "--runs none --quiet"));
    EXPECT_EQ(r.status, 0) << r.output;
    const auto record = hil::bench::read_run_record(killed);
    EXPECT_EQ(record.outcome, hil::bench::Outcome::interrupted) << r.output;
    EXPECT_NE(record.reason.value_or("").find("the hilbench run process (pid " + std::to_string(pid) + ") ended during the run"),
              std::string::npos)
        << record.reason.value_or("");
    EXPECT_NE(record.reason.value_or("").find("found by hilbench " + next + " at"), std::string::npos)
        << record.reason.value_or("");
    ASSERT_TRUE(record.telemetry && record.telemetry->rows_written);
    EXPECT_EQ(*record.telemetry->rows_written, csv_rows(killed / "telemetry.csv"));
    EXPECT_GT(*record.telemetry->rows_written, 0u);
  }
}

// A completed run: the end record in events.jsonl, JUnit with the run's wall time on its cases,
// and nothing that says it was recorded by the server.
TEST(RunInterlocks, ACompletedRunEndsItsEventsAndSaysWhoRecordedIt) {
  Base b;
  const auto file = campaign(b.dir, 0.5);
  const auto junit = b.dir.path() / "junit.xml";
  const auto r = run_command(b.command(file, "--speed 10 --quiet --junit " + q(junit)));
  ASSERT_EQ(r.status, 0) << r.output;
  const auto dirs = run_dirs(b.out);
  ASSERT_EQ(dirs.size(), 2u);
  for (const auto& d : dirs) {
    const auto ev = events(d);
    ASSERT_FALSE(ev.empty());
    EXPECT_EQ(ev.back().value("kind", ""), "run_end") << ev.back().dump();
    EXPECT_EQ(ev.back().value("outcome", ""), "completed");
    EXPECT_EQ(ev.back()["rows_written"], 500);
    EXPECT_EQ(ev.back()["checks_failed"], 0);
    const std::string csv = slurp(d / "telemetry.csv");
    EXPECT_EQ(csv.find("hilbench serve"), std::string::npos);
    EXPECT_NE(csv.find("hilbench run"), std::string::npos) << csv.substr(0, 400);
  }
  const auto report = b.dir.path() / "report.html";
  ASSERT_EQ(run_command(hilbench() + " report " + q(dirs[0]) + " " + q(dirs[1]) + " --quiet --out " + q(report)).status, 0);
  EXPECT_EQ(slurp(report).find("Recorded by hilbench serve"), std::string::npos);
  EXPECT_NE(slurp(report).find("Recorded by hilbench run:"), std::string::npos);

  const std::string xml = slurp(junit);
  EXPECT_EQ(schema_problems(junit), "") << xml;
  EXPECT_NE(xml.find("tests=\"2\" failures=\"0\" errors=\"0\""), std::string::npos) << xml;
  EXPECT_EQ(xml.find("time=\"0.000\""), std::string::npos) << "every case has its run's wall time\n" << xml;
}

// The checker sees what the Jenkins xUnit schema refuses (a checker that cannot fail is no test).
TEST(RunInterlocks, TheSchemaCheckerRefusesWhatTheSchemaRefuses) {
  hil::test::TempDir dir;
  const auto bad = dir.write("bad.xml",
                             "<testsuites skipped=\"1\"><testsuite name=\"a\" tests=\"1\" failures=\"0\">"
                             "<testcase name=\"c\" file=\"x\"><skipped/></testcase></testsuite></testsuites>\n");
  const std::string problems = schema_problems(bad);
  EXPECT_NE(problems.find("attribute 'skipped' is not allowed on <testsuites>"), std::string::npos) << problems;
  EXPECT_NE(problems.find("<testsuite> needs attribute 'errors'"), std::string::npos) << problems;
  EXPECT_NE(problems.find("attribute 'file' is not allowed on <testcase>"), std::string::npos) << problems;
}

}  // namespace
