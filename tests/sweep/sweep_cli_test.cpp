// hilbench sweep through the real binary: the same sweep.csv whatever the job count, after an
// interrupt and a resume, and over shards; config errors naming file, line and key; a point's
// metrics against the same campaign run by hilbench sim; the Slurm submission against stand-in
// sbatch and squeue programs (tests/slurm runs it on a real cluster).
#include <gtest/gtest.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <tuple>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "run_command.hpp"
#include "small_disk.hpp"
#include "temp_file.hpp"

namespace {

using hil::test::hilbench;
using hil::test::run_command;
using hil::test::slurp;
using hil::test::source_path;
using hil::test::TempDir;
namespace fs = std::filesystem;

std::string q(const fs::path& p) {
  std::string quoted(1, '\'');
  quoted += p.string();
  quoted += '\'';
  return quoted;
}

long lines_in(const fs::path& file) {
  const std::string s = slurp(file);
  return static_cast<long>(std::count(s.begin(), s.end(), '\n'));
}

std::vector<std::vector<std::string>> csv_rows(const fs::path& file) {
  std::vector<std::vector<std::string>> rows;
  std::stringstream in(slurp(file));
  for (std::string line; std::getline(in, line);) {
    std::vector<std::string> cells;
    std::stringstream l(line);
    for (std::string c; std::getline(l, c, ',');) cells.push_back(c);
    rows.push_back(cells);
  }
  return rows;
}

// A sweep of the tiny campaign over `a x b` grid values of the initial gap and the sensor noise.
fs::path write_grid_sweep(const TempDir& dir, const std::string& name, int gaps, int noises) {
  return dir.write(
      name, "name: grid\ncampaign: " + source_path("tests/sweep/data/tiny_campaign.yaml").string() +
                "\nruns: [none, adaptive]\naxes:\n  - path: campaign.gap.initial_deg\n    range: {from: 0.2, to: 2.5, count: " +
                std::to_string(gaps) +
                "}\n  - path: campaign.sensor_noise_kpa\n    range: {from: 0, to: 8, count: " + std::to_string(noises) + "}\n");
}

// Starts `hilbench ARGS...` in the background (its stderr into `err`), waits until `ready()` holds
// (at most 60 s), then sends `sig`; returns the exit status (or 128 + the signal it died of). A
// process still there 30 s after the signal is killed: a failure, not a hang.
int interrupt_when(const std::vector<std::string>& args, const fs::path& err, const std::function<bool()>& ready, int sig) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int fd = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd >= 0) ::dup2(fd, 2);
    const std::string exe = hilbench();
    std::vector<char*> argv{const_cast<char*>(exe.c_str())};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(exe.c_str(), argv.data());
    ::_exit(127);
  }
  for (const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
       std::chrono::steady_clock::now() < deadline && !ready();)
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  ::kill(pid, sig);
  int status = 0;
  for (const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);;) {
    if (::waitpid(pid, &status, WNOHANG) == pid) break;
    if (std::chrono::steady_clock::now() > deadline) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      ADD_FAILURE() << "still running 30 s after signal " << sig;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

// hilbench sweep SWEEP --out OUT --jobs 1 --quiet, signalled once its rows file holds a whole line.
int interrupt_after_first_row(const fs::path& sweep, const fs::path& out, int sig) {
  const auto rows = out / "rows" / "local.jsonl";
  return interrupt_when(
      {"sweep", sweep.string(), "--out", out.string(), "--jobs", "1", "--quiet"}, out.string() + ".err",
      [&] { return fs::exists(rows) && lines_in(rows) >= 1; }, sig);
}

TEST(Sweep, SameCsvWithOneAndTwoJobsAndAfterInterruptAndResume) {
  TempDir dir;
  const auto sweep = write_grid_sweep(dir, "grid.yaml", 10, 12);  // 120 points
  const auto one = dir.path() / "one", two = dir.path() / "two";
  ASSERT_EQ(run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(one) + " --jobs 1 --quiet").status, 0);
  ASSERT_EQ(run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(two) + " --jobs 2 --quiet").status, 0);
  const std::string expected = slurp(one / "sweep.csv");
  ASSERT_EQ(csv_rows(one / "sweep.csv").size(), 121u);
  EXPECT_EQ(slurp(two / "sweep.csv"), expected);
  EXPECT_EQ(slurp(two / "sweep.json"), slurp(one / "sweep.json"));

  // SIGINT: the point in flight finishes, the process says how to continue and exits 130 with
  // whole lines only; the rerun runs only what is missing.
  for (int sig : {SIGINT, SIGKILL}) {
    const auto out = dir.path() / ("stopped_" + std::to_string(sig));
    const int status = interrupt_after_first_row(sweep, out, sig);
    EXPECT_EQ(status, 128 + sig) << "signal " << sig;
    const auto rows = out / "rows" / "local.jsonl";
    const long before = lines_in(rows);
    ASSERT_GE(before, 1);
    ASSERT_LT(before, 120) << "the sweep finished before the signal: make it longer";
    EXPECT_FALSE(fs::exists(out / "sweep.csv"));
    if (sig == SIGINT) {
      EXPECT_EQ(slurp(rows).back(), '\n');
    }
    const auto rerun = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --jobs 2");
    ASSERT_EQ(rerun.status, 0) << rerun.output;
    EXPECT_NE(rerun.output.find("ran " + std::to_string(120 - before) + " points"), std::string::npos) << before << " before\n"
                                                                                                       << rerun.output;
    EXPECT_EQ(slurp(out / "sweep.csv"), expected) << "signal " << sig;
  }
  // A third run has nothing left to do, and says so by running nothing.
  const auto again = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(one));
  EXPECT_EQ(again.status, 0);
  EXPECT_EQ(again.output.find("ran "), std::string::npos) << again.output;
  EXPECT_EQ(slurp(one / "sweep.csv"), expected);
}

// The disk fills up part way: whole rows only, an error that says how many points are kept and
// that the same command goes on; once there is room, it runs only the rest, to the same sweep.csv.
// Before a sweep runs, every point's campaign is loaded once to check it (about a millisecond
// each): 200 000 points are minutes. That check shows its progress, and Ctrl-C stops it at once,
// writing nothing. It used to run silent, and past a first Ctrl-C (whose handler came later).
TEST(Sweep, ALargeSweepsCheckShowsProgressAndAnInterruptStopsItWritingNothing) {
  TempDir dir;
  const auto sweep = dir.write("mc.yaml", "name: mc\ncampaign: " + source_path("tests/sweep/data/tiny_campaign.yaml").string() +
                                              "\nseed: 5\nsamples: 200000\naxes:\n  - path: campaign.gap.initial_deg\n"
                                              "    uniform: {low: 0.2, high: 4}\n");
  const auto out = dir.path() / "out", err = dir.path() / "stderr.txt";
  const int status = interrupt_when(
      {"sweep", sweep.string(), "--out", out.string()}, err,
      [&] { return slurp(err).find("sweep mc: checking each point's campaign:") != std::string::npos; }, SIGINT);
  const std::string said = slurp(err);
  EXPECT_NE(said.find("sweep mc: checking each point's campaign:"), std::string::npos) << said;
  EXPECT_EQ(status, 128 + SIGINT) << said;
  EXPECT_NE(said.find("stopped by SIGINT while its points were checked; nothing was written"), std::string::npos) << said;
  EXPECT_FALSE(fs::exists(out)) << said;
}

TEST(Sweep, AFullDiskKeepsWholeRowsAndTheSameCommandGoesOn) {
  TempDir dir;
  const auto sweep = write_grid_sweep(dir, "grid.yaml", 10, 12);  // 120 points
  const auto reference = dir.path() / "reference";
  ASSERT_EQ(run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(reference) + " --jobs 2 --quiet").status, 0);
  hil::test::SmallDisk disk(dir.path() / "disk", "1m");
  if (!disk.mounted()) GTEST_SKIP() << "cannot mount a tmpfs here (not root?): the full-disk case needs its own small disk";
  const auto out = dir.path() / "disk" / "sweep";
  ASSERT_EQ(interrupt_after_first_row(sweep, out, SIGINT), 128 + SIGINT);
  const auto rows = out / "rows" / "local.jsonl";
  ASSERT_LT(lines_in(rows), 120) << "the sweep finished before the signal: make it longer";

  disk.fill();
  const auto full = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --jobs 2 --quiet");
  EXPECT_EQ(full.status, 1) << full.output;
  EXPECT_NE(full.output.find("No space left on device"), std::string::npos) << full.output;
  const long kept = lines_in(rows);
  EXPECT_EQ(slurp(rows).back(), '\n') << "the rows end on a whole line";
  EXPECT_NE(full.output.find(std::to_string(kept) + " of 120 points are kept in " + out.string() +
                             ", and the same command goes on from there"),
            std::string::npos)
      << full.output;
  EXPECT_FALSE(fs::exists(out / "sweep.csv"));

  disk.unfill();
  const auto rerun = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --jobs 2");
  ASSERT_EQ(rerun.status, 0) << rerun.output;
  EXPECT_NE(rerun.output.find("ran " + std::to_string(120 - kept) + " points"), std::string::npos) << kept << " kept\n"
                                                                                                   << rerun.output;
  EXPECT_EQ(slurp(out / "sweep.csv"), slurp(reference / "sweep.csv"));
}

// The outputs of a finished sweep are one result: a disk with room for sweep.csv but not for
// sweep.json left the new csv alone, and `--status` said "outputs written".
TEST(Sweep, OutputsAreWrittenAllOrNoneAndTheStatusSaysWhichItIs) {
  TempDir dir;
  const auto sweep = write_grid_sweep(dir, "grid.yaml", 10, 12);  // sweep.csv 13 kB, sweep.json 86 kB
  hil::test::SmallDisk disk(dir.path() / "disk", "1m");
  if (!disk.mounted()) GTEST_SKIP() << "cannot mount a tmpfs here (not root?): the full-disk case needs its own small disk";
  const auto out = dir.path() / "disk" / "sweep";
  const std::string command = hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --jobs 2 --quiet";
  ASSERT_EQ(run_command(command).status, 0);
  for (const char* f : {"sweep.csv", "sweep.json", "report.html"}) fs::remove(out / f);
  disk.fill();
  fs::resize_file(dir.path() / "disk" / "filler",
                  fs::file_size(dir.path() / "disk" / "filler") - 40 * 1024);  // room for the csv only

  const auto full = run_command(command);
  EXPECT_EQ(full.status, 1) << full.output;
  EXPECT_NE(full.output.find("No space left on device"), std::string::npos) << full.output;
  for (const char* f : {"sweep.csv", "sweep.json", "report.html"}) EXPECT_FALSE(fs::exists(out / f)) << f;
  const auto status = run_command(hilbench() + " sweep --status " + q(out));
  EXPECT_NE(status.output.find("120 of 120 points done, 0 missing\n"), std::string::npos) << status.output;

  disk.unfill();
  ASSERT_EQ(run_command(command).status, 0);
  EXPECT_NE(run_command(hilbench() + " sweep --status " + q(out)).output.find("0 missing; outputs written"), std::string::npos);
  fs::remove(out / "sweep.json");  // by hand, or by an older hilbench
  EXPECT_NE(run_command(hilbench() + " sweep --status " + q(out)).output.find("0 missing; outputs incomplete"),
            std::string::npos);
}

// Lines of a rows file that are no row of the plan (damaged, or edited by hand) are counted and
// shown; their points count as missing and run again, to the same sweep.csv.
TEST(Sweep, DamagedRowLinesAreShownAndTheirPointsRunAgain) {
  TempDir dir;
  const auto sweep = write_grid_sweep(dir, "grid.yaml", 2, 3);  // 6 points
  const auto out = dir.path() / "out";
  ASSERT_EQ(run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --quiet").status, 0);
  const std::string expected = slurp(out / "sweep.csv");
  const auto rows = out / "rows" / "local.jsonl";
  std::string text = slurp(rows);
  ASSERT_EQ(lines_in(rows), 6);
  const auto second = text.find('\n') + 1;
  text.replace(second, text.find('\n', second) - second, "{\"point\": 2, \"metr\x01");  // a damaged line
  text += "{\"point\": 6, \"metrics\": []}\n";                                          // no point of this plan
  std::ofstream(rows, std::ios::binary | std::ios::trunc) << text;

  const auto status = run_command(hilbench() + " sweep --status " + q(out));
  EXPECT_EQ(status.status, 1) << "a point is missing: " << status.output;
  EXPECT_NE(status.output.find("5 of 6 points done, 1 missing"), std::string::npos) << status.output;
  EXPECT_NE(status.output.find("to run what is missing: hilbench sweep --out '" + out.string() + "'"), std::string::npos)
      << status.output;
  EXPECT_NE(status.output.find("2 line(s) in " + (out / "rows").string() + " are no row of this sweep"), std::string::npos)
      << status.output;
  const auto rerun = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --quiet");
  EXPECT_EQ(rerun.status, 0) << rerun.output;
  EXPECT_NE(rerun.output.find("2 line(s) in " + (out / "rows").string() + " are no row of this sweep"), std::string::npos)
      << rerun.output;
  EXPECT_EQ(slurp(out / "sweep.csv"), expected);
  EXPECT_EQ(lines_in(rows), 8) << "the point is appended again; the damaged lines stay as they were";
  // The warning is a log line: --log-level error leaves it out, and changes nothing else.
  const auto quiet_log = run_command(hilbench() + " --log-level error sweep " + q(sweep) + " --out " + q(out) + " --quiet");
  EXPECT_EQ(quiet_log.status, 0) << quiet_log.output;
  EXPECT_EQ(quiet_log.output.find("are no row of this sweep"), std::string::npos) << quiet_log.output;
  EXPECT_EQ(slurp(out / "sweep.csv"), expected);
}

TEST(Sweep, ChangedSweepFileIsRefusedForAPlannedFolder) {
  TempDir dir;
  const auto sweep = write_grid_sweep(dir, "grid.yaml", 2, 2);
  const auto out = dir.path() / "out";
  ASSERT_EQ(run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --quiet").status, 0);
  write_grid_sweep(dir, "grid.yaml", 3, 2);
  const auto r = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("was planned from another sweep"), std::string::npos) << r.output;
  EXPECT_EQ(csv_rows(out / "sweep.csv").size(), 5u);  // the first sweep's outputs stay
}

// c.yaml in `dir`: the tiny campaign with its square reference replaced by the csv `reference`.
void write_csv_campaign(const TempDir& dir, const std::string& reference) {
  std::string campaign = slurp(source_path("tests/sweep/data/tiny_campaign.yaml"));
  const std::string plant_line = "plant: ../../../configs/plant/nominal.yaml";
  campaign.replace(campaign.find(plant_line), plant_line.size(), "plant: " + source_path("configs/plant/nominal.yaml").string());
  const auto square = campaign.find("    - square:");
  campaign.replace(square, campaign.find('\n', square) - square, "    - csv: {file: " + reference + ", column: p_mpa}");
  dir.write("c.yaml", campaign);
}

// A csv reference alternating 1.0 and `high_mpa` each second for 5 s.
fs::path write_csv_reference(const TempDir& dir, const std::string& name, double high_mpa) {
  std::string csv = "t_s,p_mpa\n";
  for (int k = 0; k <= 5; ++k) csv += std::to_string(k) + "," + std::to_string(k % 2 == 1 ? high_mpa : 1.0) + "\n";
  return dir.write(name, csv);
}

// Every point reads the campaign's csv reference again: a resumed sweep whose csv changed would
// mix rows of the old reference with rows of the new one, so the plan fingerprints its content.
TEST(Sweep, AChangedCsvReferenceIsAnotherSweep) {
  TempDir dir;
  write_csv_campaign(dir, "ref.csv");
  const auto write_reference = [&](double high_mpa) { write_csv_reference(dir, "ref.csv", high_mpa); };
  write_reference(1.4);
  const auto sweep = dir.write("s.yaml", "campaign: c.yaml\nruns: [none]\naxes:\n  - path: campaign.seed\n    values: [5, 6]\n");
  const auto out = dir.path() / "out";
  auto r = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --quiet");
  ASSERT_EQ(r.status, 0) << r.output;
  write_reference(1.3);
  r = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --quiet");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("a file the campaign reads (a csv reference) changed"), std::string::npos) << r.output;
}

// A csv reference that an axis names (not the base campaign's own) is fingerprinted too, and so
// is every file a shard run reads: a sweep resumed, or a shard run with only the folder, after
// such a file changed would mix rows of the old contents with rows of the new.
TEST(Sweep, AChangedFileThatAnAxisNamesStopsAResumeAndAShard) {
  TempDir dir;
  write_csv_campaign(dir, "a.csv");
  const auto write_reference = [&](const std::string& name, double high_mpa) { return write_csv_reference(dir, name, high_mpa); };
  write_reference("a.csv", 1.4);
  const auto b = write_reference("b.csv", 1.3);
  const auto sweep = dir.write(
      "s.yaml", "campaign: c.yaml\nruns: [none]\naxes:\n  - path: campaign.reference.profile[0].csv.file\n    values: [a.csv, " +
                    b.string() + "]\n  - path: campaign.seed\n    values: [5, 6, 7]\n");
  const auto out = dir.path() / "out";
  // Shard 0 of 2 runs points 0, 2, 4; the plan lists both files.
  auto r = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --shard 0/2 --quiet");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto plan = nlohmann::json::parse(slurp(out / "plan.json"));
  ASSERT_EQ(plan.at("input_files").size(), 2u) << plan.at("input_files");
  write_reference("b.csv", 1.25);
  const std::string refused = b.string() + ": a file the sweep's points read has changed since " + out.string() + " was planned";
  r = run_command(hilbench() + " sweep --out " + q(out) + " --shard 1/2 --quiet");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find(refused), std::string::npos) << r.output;
  r = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --quiet");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find(refused), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out / "rows" / "local.jsonl"));
  // Put back, the same command goes on.
  write_reference("b.csv", 1.3);
  r = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --quiet");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(csv_rows(out / "sweep.csv").size(), 7u);
}

TEST(Sweep, BadAxisPathOrSpecNamesTheSweepFileLineAndKey) {
  TempDir dir;
  const std::string head = "campaign: " + source_path("tests/sweep/data/tiny_campaign.yaml").string() + "\naxes:\n";
  struct Case {
    std::string axes;
    std::string where;  // file:line:column: key
    std::string why;
  };
  const std::vector<Case> cases = {
      {"  - path: campaign.gap.initial_dg\n    values: [1, 2]\n", "bad.yaml:3:5: axes[0].path", "no key 'initial_dg'"},
      {"  - path: campaign.sensor_noise_kpa\n    values: [1]\n  - path: campaign.gap.changes[2].drift.to_deg\n    values: [1]\n",
       "bad.yaml:5:5: axes[1].path", "no item [2]"},
      {"  - path: plant.effects.motor_servo.time_constnt_s\n    values: [0.01]\n", "bad.yaml:3:5: axes[0].path",
       "nominal.yaml has no key 'time_constnt_s'"},
      {"  - path: gap.initial_deg\n    values: [1]\n", "bad.yaml:3:5: axes[0].path", "no axis path"},
      {"  - path: campaign.runs[0].name\n    values: [x]\n", "bad.yaml:3:5: axes[0].path", "run names cannot be an axis"},
      {"  - path: campaign.runs\n    values: [x]\n", "bad.yaml:3:5: axes[0].path", "which is no single value"},
      {"  - path: campaign.gap.initial_deg\n    range: {from: 1, to: 2}\n", "bad.yaml:4:5: axes[0].range",
       "missing required key 'count'"},
      {"  - path: campaign.gap.initial_deg\n    range: {from: 0, to: 2, count: 3, scale: log}\n", "bad.yaml:4:5: axes[0].range",
       "log range needs from > 0"},
      {"  - path: campaign.gap.initial_deg\n    uniform: {low: 1, high: 2}\n", "bad.yaml:1:1", "missing required key 'samples'"},
      {"  - path: campaign.gap.initial_deg\n    values: [1]\n    range: {from: 1, to: 1, count: 1}\n", "bad.yaml:3:5: axes[0]",
       "exactly one of"},
      // An axis's words for the report: one line of text each.
      {"  - path: campaign.gap.initial_deg\n    values: [1]\n    label: \"\"\n", "bad.yaml:5:5: axes[0].label",
       "must not be empty"},
      {"  - path: campaign.gap.initial_deg\n    values: [1]\n    unit: [deg]\n", "bad.yaml:5:5: axes[0].unit", "must be a text"},
      {"  - path: campaign.gap.initial_deg\n    values: [1]\n    unit: \"a unit longer than sixteen\"\n",
       "bad.yaml:5:5: axes[0].unit", "at most 16 characters"},
      {"  - path: campaign.gap.initial_deg\n    values: [1]\n    lable: gap\n", "bad.yaml:5:5: axes[0].lable",
       "did you mean 'label'"},
      // Too many points: the product that makes them, so the user sees which axis to thin.
      {"  - path: campaign.gap.initial_deg\n    range: {from: 1, to: 2, count: 10000}\n  - path: campaign.sensor_noise_kpa\n"
       "    range: {from: 0, to: 5, count: 10000}\n  - path: campaign.seed\n    range: {from: 1, to: 9, count: 9}\n",
       "bad.yaml:2:1: axes", "10000 x 10000 x 9 = 9e+08 points; a sweep has at most 1000000"},
  };
  for (const auto& c : cases) {
    const auto file = dir.write("bad.yaml", head + c.axes);
    const auto out = dir.path() / "out";
    const auto r = run_command(hilbench() + " sweep " + q(file) + " --out " + q(out));
    EXPECT_EQ(r.status, 1) << c.axes << r.output;
    EXPECT_NE(r.output.find(c.where), std::string::npos) << c.axes << r.output;
    EXPECT_NE(r.output.find(c.why), std::string::npos) << c.axes << r.output;
    EXPECT_FALSE(fs::exists(out)) << "nothing is written before the sweep is valid";
  }
  // A value the campaign's own loader refuses gets the loader's error, naming the point.
  const auto file = dir.write("bad.yaml", head + "  - path: campaign.gap.initial_deg\n    values: [1, -0.5]\n");
  const auto r = run_command(hilbench() + " sweep " + q(file) + " --out " + q(dir.path() / "out"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("point 1 (campaign.gap.initial_deg = -0.5)"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("gap.initial_deg: a gap cannot be negative"), std::string::npos) << r.output;
}

// Two sweeps on one --out (one shard) do not share its rows file: the second is refused before it
// plans any work, while the first holds the lock; once that is gone the same command goes on.
// A FIFO in the rows file's place is refused, not waited on.
TEST(Sweep, ASecondSweepOnTheSameRowsIsRefusedAndAFifoIsNotWaitedOn) {
  TempDir dir;
  const auto sweep = dir.write("s.yaml", "campaign: " + source_path("tests/sweep/data/tiny_campaign.yaml").string() +
                                             "\nruns: [none]\naxes:\n  - path: campaign.seed\n    values: [5, 6]\n");
  const auto out = dir.path() / "out";
  fs::create_directories(out / "rows");
  const auto lock_file = out / "rows" / ".local.jsonl.lock";
  const int fd = ::open(lock_file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::flock(fd, LOCK_EX), 0);  // what a running sweep holds
  auto r = run_command("timeout 60 " + hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --quiet");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("another hilbench sweep is writing"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out / "rows" / "local.jsonl"));  // nothing run, nothing written
  ::close(fd);
  r = run_command("timeout 60 " + hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --quiet");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(csv_rows(out / "sweep.csv").size(), 3u);

  const auto out2 = dir.path() / "out2";
  fs::create_directories(out2 / "rows");
  ASSERT_EQ(::mkfifo((out2 / "rows" / "local.jsonl").c_str(), 0600), 0);
  r = run_command("timeout 60 " + hilbench() + " sweep " + q(sweep) + " --out " + q(out2) + " --quiet");
  EXPECT_EQ(r.status, 1) << r.output;  // 124 would be the timeout: a hang
  EXPECT_NE(r.output.find("local.jsonl"), std::string::npos) << r.output;
}

// The metrics of a sweep point from that point's campaign run by hilbench sim, computed here from
// its summary.json: IAE, mean stall over the reversals, that over the none run's, touch changes
// per reversal, mean |gap estimate - true gap| over reversals 2..n.
TEST(Sweep, APointsMetricsAreThoseOfTheSameCampaignRunBySim) {
  TempDir dir;
  const auto sweep = dir.write("s.yaml", "campaign: " + source_path("tests/sweep/data/tiny_campaign.yaml").string() +
                                             "\nruns: [none, adaptive_paper]\naxes:\n"
                                             "  - path: plant.effects.motor_servo.time_constant_s\n    values: [0.005, 0.03]\n"
                                             "  - path: campaign.reference.profile[0].square.high_mpa\n    values: [1.3, 1.5]\n"
                                             "  - path: campaign.seed\n    values: [5]\n");
  const auto out = dir.path() / "out";
  const auto r = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --quiet");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto rows = csv_rows(out / "sweep.csv");
  ASSERT_EQ(rows.size(), 5u);
  const auto& header = rows[0];
  int checked = 0;
  for (const auto& e : fs::directory_iterator(out / "points")) {
    const long p = std::stol(e.path().filename().string());
    const auto sim_out = dir.path() / ("sim" + std::to_string(p));
    const auto s =
        run_command(hilbench() + " sim " + q(e.path() / "campaign.yaml") + " --out " + q(sim_out) + " --no-telemetry --quiet");
    ASSERT_EQ(s.status, 0) << s.output;
    const auto& row = rows.at(static_cast<std::size_t>(p) + 1);
    auto summary = [&](const std::string& run) { return nlohmann::json::parse(slurp(sim_out / "tiny" / run / "summary.json")); };
    auto stall_per_reversal = [](const nlohmann::json& j) {
      double sum = 0;
      for (const auto& rev : j["reversals"]) sum += rev["stall_s"].get<double>();
      return sum / static_cast<double>(j["reversals"].size());
    };
    const double none_stall = stall_per_reversal(summary("none"));
    for (const std::string run : {"none", "adaptive_paper"}) {
      const auto j = summary(run);
      const auto& revs = j["reversals"];
      ASSERT_GE(revs.size(), 2u);
      double gap_err = 0;
      for (std::size_t k = 1; k < revs.size(); ++k)
        gap_err += std::abs(revs[k]["gap_est_deg"].get<double>() - revs[k]["gap_true_deg"].get<double>());
      gap_err /= static_cast<double>(revs.size() - 1);
      const std::vector<std::pair<std::string, double>> expected = {
          {"iae_mpa_s", j["iae_mpa_s"].get<double>()},
          {"stall_s_per_reversal", stall_per_reversal(j)},
          {"stall_vs_none", stall_per_reversal(j) / none_stall},
          {"touch_changes_per_reversal", j["touch_state_changes"].get<double>() / static_cast<double>(revs.size())},
          {"gap_error_deg", gap_err},
          {"interlock_trips", 0.0},  // 1.0-1.4 MPa stays far inside the default 0.2-2.5 MPa limits
      };
      for (const auto& [metric, value] : expected) {
        const auto col = std::find(header.begin(), header.end(), run + "." + metric) - header.begin();
        ASSERT_LT(static_cast<std::size_t>(col), header.size()) << metric;
        char want[32];
        std::snprintf(want, sizeof want, "%.6g", value);
        EXPECT_EQ(row.at(static_cast<std::size_t>(col)), want) << "point " << p << " " << run << "." << metric;
      }
    }
    ++checked;
  }
  EXPECT_EQ(checked, 4);  // every point is among the 10 worst of 4
}

// relative_to: the axis's value is an increment on another path's value at that point.
TEST(Sweep, RelativeAxisAddsToTheValueItNames) {
  TempDir dir;
  const auto sweep =
      dir.write("s.yaml", "campaign: " + source_path("tests/sweep/data/tiny_campaign.yaml").string() +
                              "\nruns: [adaptive]\naxes:\n  - path: campaign.gap.initial_deg\n    values: [0.5, 2]\n"
                              "  - path: campaign.gap.changes[0].drift.to_deg\n    relative_to: campaign.gap.initial_deg\n"
                              "    values: [+0.25]\n");  // YAML allows the sign
  const auto out = dir.path() / "out";
  const auto r = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --quiet");
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string p0 = slurp(out / "points" / "0" / "campaign.yaml"), p1 = slurp(out / "points" / "1" / "campaign.yaml");
  EXPECT_NE(p0.find("initial_deg: 0.5"), std::string::npos) << p0;
  EXPECT_NE(p0.find("to_deg: 0.75"), std::string::npos) << p0;
  EXPECT_NE(p1.find("initial_deg: 2"), std::string::npos) << p1;
  EXPECT_NE(p1.find("to_deg: 2.25"), std::string::npos) << p1;
  EXPECT_EQ(p1.find("adaptive_paper"), std::string::npos) << "only the sweep's runs\n" << p1;
}

// An increment on an increment depends on the order they are applied in, and two axes relative
// to each other (a cycle) ran with whatever that order made: both refused at the relative_to,
// naming the line, before anything runs.
TEST(Sweep, ARelativeAxisOnAnotherIncrementIsRefused) {
  TempDir dir;
  const std::string head =
      "campaign: " + source_path("tests/sweep/data/tiny_campaign.yaml").string() + "\nruns: [adaptive]\naxes:\n";
  const std::string cycle = head +
                            "  - path: campaign.gap.initial_deg\n    relative_to: campaign.gap.changes[0].drift.to_deg\n"
                            "    values: [0.1]\n"
                            "  - path: campaign.gap.changes[0].drift.to_deg\n    relative_to: campaign.gap.initial_deg\n"
                            "    values: [0.25]\n";
  const std::string chain = head +
                            "  - path: campaign.seed\n    values: [1, 2]\n"
                            "  - path: campaign.gap.initial_deg\n    relative_to: campaign.duration_s\n    values: [-3.5]\n"
                            "  - path: campaign.gap.changes[0].drift.to_deg\n    relative_to: campaign.gap.initial_deg\n"
                            "    values: [0.25]\n";
  for (const auto& [name, text, line] : {std::tuple{"cycle", cycle, 5}, std::tuple{"chain", chain, 10}}) {
    const auto sweep = dir.write(std::string(name) + ".yaml", text);
    const auto out = dir.path() / ("out_" + std::string(name));
    const auto r = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --quiet");
    EXPECT_NE(r.status, 0) << name << "\n" << r.output;
    EXPECT_NE(r.output.find(std::string(name) + ".yaml:" + std::to_string(line) + ":"), std::string::npos) << name << "\n"
                                                                                                           << r.output;
    EXPECT_NE(r.output.find("is itself an increment"), std::string::npos) << name << "\n" << r.output;
    EXPECT_FALSE(std::filesystem::exists(out / "sweep.csv")) << name;
  }
}

// A reference from a CSV file beside the base campaign: the point's campaign, written elsewhere,
// still finds it, and reproduces the sweep's numbers.
TEST(Sweep, APointsCampaignFindsTheBaseCampaignsReferenceFile) {
  TempDir dir;
  const auto sweep =
      dir.write("s.yaml", "campaign: " + source_path("tests/sweep/data/tiny_csv_campaign.yaml").string() +
                              "\nruns: [adaptive]\naxes:\n  - path: campaign.gap.initial_deg\n    values: [0.5, 2]\n");
  const auto out = dir.path() / "out";
  const auto r = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --quiet");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto sim = run_command(hilbench() + " sim " + q(out / "points" / "1" / "campaign.yaml") + " --out " +
                               q(dir.path() / "sim") + " --no-telemetry --quiet");
  ASSERT_EQ(sim.status, 0) << sim.output;
  const auto j = nlohmann::json::parse(slurp(dir.path() / "sim" / "tiny_csv" / "adaptive" / "summary.json"));
  EXPECT_EQ(j["reversals"].size(), 4u);
  char iae[32];
  std::snprintf(iae, sizeof iae, "%.6g", j["iae_mpa_s"].get<double>());
  EXPECT_EQ(csv_rows(out / "sweep.csv").at(2).at(2), iae);
}

// plan.json is a file anyone may edit: an aggregation of an edited one is an error naming it,
// not a division by zero samples, an allocation from a bogus axis, or a read past a metric list.
TEST(Sweep, AnEditedPlanIsRefusedNotCrashedOn) {
  TempDir dir;
  const auto out = dir.path() / "out";
  ASSERT_EQ(
      run_command(hilbench() + " sweep " + q(source_path("tests/sweep/small.yaml")) + " --out " + q(out) + " --quiet").status, 0);
  const auto plan = nlohmann::json::parse(slurp(out / "plan.json"));
  const std::vector<std::pair<std::string, std::function<void(nlohmann::json&)>>> edits = {
      {"samples must be >= 1", [](nlohmann::json& j) { j["samples"] = 0; }},
      {"no list or range axis 'nope'",
       [](nlohmann::json& j) {
         j["maps"] = {
             {{"metric", j["worst_by"]}, {"x", "nope"}, {"y", "nope"}, {"reduce", "mean"}, {"slice", nlohmann::json::array()}}};
       }},
      {"no metric 'adaptive.nothing'", [](nlohmann::json& j) { j["worst_by"] = "adaptive.nothing"; }},
  };
  for (const auto& [why, edit] : edits) {
    nlohmann::json j = plan;
    edit(j);
    std::ofstream(out / "plan.json") << j.dump(1);
    const auto r = run_command(hilbench() + " sweep --out " + q(out) + " --aggregate");
    EXPECT_EQ(r.status, 1) << why << "\n" << r.output;  // 136 was SIGFPE
    EXPECT_NE(r.output.find("plan.json: " + why), std::string::npos) << r.output;
  }
}

TEST(Sweep, ShardsAndAggregateGiveTheLocalSweep) {
  TempDir dir;
  const auto sweep = source_path("tests/sweep/small.yaml");
  const auto local = dir.path() / "local", sharded = dir.path() / "sharded";
  ASSERT_EQ(run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(local) + " --quiet").status, 0);
  ASSERT_EQ(run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(sharded) + " --shard 0/4 --quiet").status, 0);
  // Later shards need only the folder: the plan is in it.
  ASSERT_EQ(run_command(hilbench() + " sweep --out " + q(sharded) + " --shard 1/4 --quiet").status, 0);
  ASSERT_EQ(run_command(hilbench() + " sweep --out " + q(sharded) + " --shard 3/4 --quiet").status, 0);
  const auto status = run_command(hilbench() + " sweep --status " + q(sharded));
  EXPECT_EQ(status.status, 1) << "a point is missing";
  EXPECT_NE(status.output.find("5 of 6 points done, 1 missing"), std::string::npos) << status.output;
  // Shard 2 of 4 (point 2 alone of 0..5) is missing: nothing final is written.
  const auto partial = run_command(hilbench() + " sweep --out " + q(sharded) + " --aggregate");
  EXPECT_EQ(partial.status, 1);
  EXPECT_NE(partial.output.find("1 of 6 points missing"), std::string::npos) << partial.output;
  EXPECT_FALSE(fs::exists(sharded / "sweep.csv"));
  ASSERT_EQ(run_command(hilbench() + " sweep --out " + q(sharded) + " --shard 2/4 --quiet").status, 0);
  const auto full = run_command(hilbench() + " sweep --out " + q(sharded) + " --aggregate");
  ASSERT_EQ(full.status, 0) << full.output;
  EXPECT_EQ(slurp(sharded / "sweep.csv"), slurp(local / "sweep.csv"));
  EXPECT_EQ(slurp(sharded / "sweep.json"), slurp(local / "sweep.json"));
  EXPECT_EQ(csv_rows(local / "sweep.csv").size(), 7u);
  const std::string html = slurp(local / "report.html");
  EXPECT_NE(html.find("adaptive.stall_vs_none"), std::string::npos);
  EXPECT_NE(html.find("hilbench sim " + (local / "points").string()), std::string::npos);
}

// --shard I/N out of its range is a usage error before anything is planned; a huge N overflowed
// the shard's stride.
TEST(Sweep, AShardOutOfItsRangeIsAUsageError) {
  TempDir dir;
  const auto sweep = source_path("tests/sweep/small.yaml");
  const auto out = dir.path() / "out";
  for (const char* shard : {"4/4", "0/0", "-1/4", "0/1000001", "1/9223372036854775807", "0/4x", "1"}) {
    const auto r = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --shard " + shard);
    EXPECT_EQ(r.status, 2) << shard << "\n" << r.output;
    EXPECT_NE(r.output.find(std::string("--shard ") + shard + ": needs I/N with 0 <= I < N <= 1000000"), std::string::npos)
        << r.output;
    EXPECT_FALSE(fs::exists(out)) << shard;
  }
  EXPECT_EQ(run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --shard 999999/1000000 --quiet").status, 0);
}

// --slurm against stand-ins for sbatch and squeue that record what they were asked: the array
// covers the shards with missing points, the aggregation job waits for it (afterany), the
// scripts run this binary on this folder, and --status asks squeue about both jobs.
TEST(Sweep, SlurmSubmitsAnArrayAndAnAggregationJobAfterIt) {
  TempDir dir;
  const auto bin = dir.path() / "bin";
  fs::create_directories(bin);
  const auto log = dir.path() / "sbatch.log";
  dir.write("bin/sbatch",
            "#!/bin/sh\necho \"$@\" >> " + q(log) + "\ncase \"$*\" in *--array*) echo 101;; *) echo '102;cluster';; esac\n");
  // squeue -h -r -j ID -o '%i|%T': one line per task still queued; the aggregation job is gone.
  dir.write("bin/squeue",
            "#!/bin/sh\ncase \"$*\" in *101*) echo '101_0|RUNNING'; echo '101_2|PENDING'; echo '101_4|PENDING';; esac\nexit 0\n");
  // No accounting (sacct fails) and slurmctld forgot nothing yet (scontrol fails: no such config).
  dir.write("bin/sacct", "#!/bin/sh\necho 'sacct: error: Slurm accounting storage is disabled' >&2\nexit 1\n");
  dir.write("bin/scontrol", "#!/bin/sh\nexit 1\n");
  for (const char* tool : {"sbatch", "squeue", "sacct", "scontrol"}) fs::permissions(bin / tool, fs::perms::owner_all);
  const std::string env = "PATH=" + q(bin) + ":\"$PATH\" ";
  const auto out = dir.path() / "out";
  const auto sweep = source_path("tests/sweep/small.yaml");
  // Shard 1 of 3 (points 1 and 4) already done: only shards 0 and 2 are submitted.
  ASSERT_EQ(run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(out) + " --shard 1/3 --quiet").status, 0);
  const auto r = run_command(env + hilbench() + " sweep " + q(sweep) + " --out " + q(out) +
                             " --slurm --tasks 3 --max-parallel 2 --partition debug --time 1:30:00 --mem 2G --account lab"
                             " --qos short --cpus-per-task 2 --sbatch-arg=--constraint=avx2");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("array 101"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("aggregate 102"), std::string::npos) << r.output;
  const std::string calls = slurp(log);
  // The resources go to both jobs; the CPUs per task to the array's tasks only.
  const std::string resources =
      "--parsable --partition=debug --time=1:30:00 --mem=2G --account=lab --qos=short --constraint=avx2 ";
  // Each job's name and logs on sbatch's command line, never in the script: a log per attempt, so
  // that a resubmission keeps the failed attempt's error.
  const std::string logs = (out / "slurm" / "logs").string();
  EXPECT_NE(calls.find(resources + "--cpus-per-task=2 --array=0,2%2 --job-name=sweep-small --output=" + logs +
                       "/shard-%A_%a.out --error=" + logs + "/shard-%A_%a.err " + (out / "slurm" / "array.sh").string()),
            std::string::npos)
      << calls;
  EXPECT_NE(calls.find(resources + "--dependency=afterany:101 --job-name=sweep-small-aggregate --output=" + logs +
                       "/aggregate-%j.out --error=" + logs + "/aggregate-%j.err " + (out / "slurm" / "aggregate.sh").string()),
            std::string::npos)
      << calls;
  const std::string array = slurp(out / "slurm" / "array.sh");
  EXPECT_NE(array.find(fs::canonical(hilbench()).string()), std::string::npos) << array;
  EXPECT_NE(array.find("--shard \"${SLURM_ARRAY_TASK_ID}/3\" --jobs \"${SLURM_CPUS_PER_TASK:-1}\""), std::string::npos) << array;
  EXPECT_NE(slurp(out / "slurm" / "aggregate.sh").find("--aggregate"), std::string::npos);
  const auto jobs = nlohmann::json::parse(slurp(out / "slurm" / "jobs.json"));
  EXPECT_EQ(jobs["submissions"][0]["array"], "101");
  EXPECT_EQ(jobs["submissions"][0]["aggregate"], "102");
  const auto status = run_command(env + hilbench() + " sweep --status " + q(out));
  EXPECT_EQ(status.status, 3) << "still running: " << status.output;
  EXPECT_NE(status.output.find("2 of 6 points done, 4 missing"), std::string::npos) << status.output;
  EXPECT_NE(status.output.find("array job 101"), std::string::npos) << status.output;
  EXPECT_NE(status.output.find("PENDING x2, RUNNING (squeue)"), std::string::npos) << status.output;
  EXPECT_NE(status.output.find("aggregate job 102 (submitted"), std::string::npos) << status.output;
  EXPECT_NE(status.output.find("Slurm no longer knows its state"), std::string::npos) << status.output;

  // Finished, one task failed (sacct's final states): --status names the task, its exit code and
  // the last line of its error log, the aggregation's own error, and the command that resubmits
  // with the same options; it exits 1.
  dir.write("bin/sacct",
            "#!/bin/sh\ncase \"$*\" in *101*) echo '101_0|COMPLETED|0:0'; echo '101_2|FAILED|1:0';; "
            "*102*) echo '102|FAILED|1:0';; esac\n");
  dir.write("out/slurm/logs/shard-101_2.err", "sweep small shard 2/3: 0% (0/2 points)\nerror: rows: Is a directory\n");
  dir.write("out/slurm/logs/aggregate-102.err", "sweep small: 4 of 6 points missing in x; nothing written\n");
  const auto failed = run_command(env + hilbench() + " sweep --status " + q(out));
  EXPECT_EQ(failed.status, 1) << failed.output;
  EXPECT_NE(failed.output.find("COMPLETED, FAILED (sacct)"), std::string::npos) << failed.output;
  EXPECT_NE(failed.output.find("FAILED: array job 101_2 FAILED (exit 1:0): error: rows: Is a directory"), std::string::npos)
      << failed.output;
  EXPECT_NE(failed.output.find("aggregation job 102 said: sweep small: 4 of 6 points missing"), std::string::npos)
      << failed.output;
  EXPECT_NE(failed.output.find("hilbench sweep --out '" + out.string() +
                               "' --slurm --tasks 3 --max-parallel 2 --partition 'debug' --time '1:30:00' --mem '2G' "
                               "--account 'lab' --qos 'short' --cpus-per-task 2 --sbatch-arg='--constraint=avx2'"),
            std::string::npos)
      << failed.output;

  // Options sbatch would refuse, or that take over what the submission sets, are usage errors.
  for (const auto& [option, says] : std::vector<std::pair<std::string, std::string>>{
           {"--time 1h", "--time '1h': not a Slurm time limit"},
           {"--mem 2GB", "--mem '2GB': not a Slurm memory size"},
           {"--account 'a b'", "--account 'a b': not a Slurm account name"},
           {"--sbatch-arg=--array=1-3", "--array is set by hilbench sweep --slurm itself"},
           {"--sbatch-arg=-o/tmp/x", "-o is set by hilbench sweep --slurm itself"},
           {"--sbatch-arg=constraint", "one sbatch option, as sbatch takes it"}}) {
    const auto refused = run_command(env + hilbench() + " sweep --out " + q(out) + " --slurm " + option);
    EXPECT_EQ(refused.status, 2) << option << ": " << refused.output;
    EXPECT_NE(refused.output.find(says), std::string::npos) << option << ": " << refused.output;
  }
  const auto local_only = run_command(hilbench() + " sweep --out " + q(out) + " --cpus-per-task 2");
  EXPECT_EQ(local_only.status, 2) << local_only.output;
  EXPECT_NE(local_only.output.find("--cpus-per-task goes with --slurm"), std::string::npos) << local_only.output;

  // sbatch refusing: its own words, exit 1.
  dir.write("bin/sbatch", "#!/bin/sh\necho 'sbatch: error: invalid partition specified: nope' >&2\nexit 1\n");
  fs::permissions(bin / "sbatch", fs::perms::owner_all);
  const auto bad = run_command(env + hilbench() + " sweep --out " + q(out) + " --slurm --partition nope");
  EXPECT_EQ(bad.status, 1);
  EXPECT_NE(bad.output.find("invalid partition specified: nope"), std::string::npos) << bad.output;
  // No sbatch at all.
  const auto none = run_command("PATH=" + q(dir.path() / "empty") + " " + hilbench() + " sweep --out " + q(out) + " --slurm");
  EXPECT_EQ(none.status, 1);
  EXPECT_NE(none.output.find("sbatch not found"), std::string::npos) << none.output;
}

}  // namespace
