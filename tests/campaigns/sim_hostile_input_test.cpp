// `hilbench sim` with input a careless or hostile user gives it: names that would point outside
// --out, absurd numbers, duplicate keys, a plant path that is no file; and a sim that fails or is
// killed. Each must end in a clear error naming where, and touch nothing outside --out.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>
#include <thread>

#include "hil/file_lock.hpp"
#include "support/run_command.hpp"
#include "support/temp_file.hpp"

using hil::test::hilbench;
using hil::test::run_command;
using hil::test::source_path;

namespace {

// A short valid campaign with the given lines replacing its defaults (the plant is the shipped one).
std::string campaign_yaml(const std::string& name_line, const std::string& extra = "", const std::string& runs = "") {
  return name_line +
         "\n"
         "plant: " +
         source_path("configs/plant/nominal.yaml").string() +
         "\n"
         "duration_s: 1\n"
         "reference: {initial_mpa: 1.0, profile: [{step: {at_s: 0.3, to_mpa: 1.2}}]}\n" +
         extra + "runs:\n" + (runs.empty() ? "  - {name: none, compensation: none}\n" : runs);
}

// Every path below `dir`, to compare a tree before and after.
std::set<std::string> tree(const std::filesystem::path& dir) {
  std::set<std::string> out;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir)) out.insert(e.path().string());
  return out;
}

struct Sandbox {
  hil::test::TempDir root;
  std::filesystem::path out = root.path() / "out";
  Sandbox() {
    std::filesystem::create_directories(out);
    root.write("precious.txt", "must survive\n");
    root.write("out/old/keep.txt", "must survive too\n");
  }
  hil::test::CommandResult sim(const std::string& yaml, const std::string& file = "c.yaml") const {
    const auto path = root.write("cfg/" + file, yaml);
    return run_command(hilbench() + " sim " + path.string() + " --out " + out.string() + " --quiet");
  }
  // `hilbench sim` of a 3000 s campaign `long` in the background, once its unpublished
  // telemetry.csv holds more than `bytes` (at most 30 s); `started` false if it never did.
  struct LongSim {
    pid_t pid;
    std::filesystem::path tmp;  // its unpublished folder
    bool started;
  };
  LongSim start_long_sim(std::uintmax_t bytes) const {
    std::string yaml = campaign_yaml("name: long");
    yaml.replace(yaml.find("duration_s: 1"), 13, "duration_s: 3000");
    const auto file = root.write("cfg/long.yaml", yaml);
    const pid_t pid = fork();
    if (pid == 0) {
      execl(hilbench().c_str(), hilbench().c_str(), "sim", file.c_str(), "--out", out.c_str(), "--quiet", nullptr);
      _exit(127);
    }
    const auto tmp = out / (".long.tmp-" + std::to_string(pid));
    const auto telemetry = tmp / "none" / "telemetry.csv";
    std::error_code ec;
    const auto written = [&] {
      return std::filesystem::exists(telemetry, ec) && std::filesystem::file_size(telemetry, ec) > bytes;
    };
    for (int i = 0; i < 3000 && !written(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    return {pid, tmp, written()};
  }
};

TEST(SimHostileInput, CampaignNamesThatWouldLeaveOutAreRefusedNamingTheKey) {
  for (const char* bad : {"..", ".", "../x", "a/b", "''", ".hidden", "x y"}) {
    Sandbox s;
    const auto before = tree(s.out);
    const auto r = s.sim(campaign_yaml(std::string("name: ") + bad));
    EXPECT_EQ(r.status, 1) << bad << "\n" << r.output;
    EXPECT_NE(r.output.find("c.yaml:1:1: name: must be a plain name"), std::string::npos) << bad << "\n" << r.output;
    EXPECT_EQ(r.output.find("got a mapping"), std::string::npos) << r.output;
    EXPECT_EQ(tree(s.out), before) << bad;
    EXPECT_TRUE(std::filesystem::exists(s.root.path() / "precious.txt"));
  }
}

TEST(SimHostileInput, RunNamesThatWouldLeaveTheCampaignFolderAreRefused) {
  for (const char* bad : {"..", ".", "a/b", "''"}) {
    Sandbox s;
    const auto before = tree(s.out);
    const auto r = s.sim(campaign_yaml("name: ok", "", std::string("  - {name: ") + bad + ", compensation: none}\n"));
    EXPECT_EQ(r.status, 1) << bad << "\n" << r.output;
    EXPECT_NE(r.output.find("runs[0].name: must be a plain name"), std::string::npos) << bad << "\n" << r.output;
    EXPECT_EQ(tree(s.out), before) << bad;
    EXPECT_TRUE(std::filesystem::exists(s.root.path() / "precious.txt"));
  }
}

TEST(SimHostileInput, AbsurdNumbersAreRefusedBeforeAnythingRuns) {
  struct Case {
    std::string yaml, expect;
  };
  const Case cases[] = {
      {campaign_yaml("name: x").replace(campaign_yaml("name: x").find("duration_s: 1"), 13, "duration_s: 1e308"),
       "duration_s: must be > 0 and at most 604800 s"},
      {campaign_yaml("name: x", "gap: {initial_deg: 1e308}\n"),
       "gap.initial_deg: a gap of 1e+308 deg is more than the backlash effect allows"},
      {campaign_yaml("name: x", "gap: {changes: [{step: {at_s: 0.5, to_deg: 500}}]}\n"), "a gap of 500 deg is more than"},
      {campaign_yaml("name: x", "seed: 1\nseed: 2\n"), "duplicate key 'seed'"},
  };
  for (const auto& c : cases) {
    Sandbox s;
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = s.sim(c.yaml);
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << "want: " << c.expect << "\ngot: " << r.output;
    EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(60));  // a refusal, not a run
    EXPECT_TRUE(std::filesystem::is_empty(s.out / "old") == false);
    EXPECT_EQ(tree(s.out).size(), 2u);  // old/ and old/keep.txt: nothing new
  }
}

TEST(SimHostileInput, PlantPathThatIsAFifoOrAFolderIsAClearErrorNotAHang) {
  Sandbox s;
  const auto fifo = s.root.path() / "plant.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const auto& [plant, why] : {std::pair{fifo, "is not a regular file"}, std::pair{s.root.path(), "is a folder"}}) {
    std::string yaml = campaign_yaml("name: x");
    yaml.replace(yaml.find("plant: "), yaml.find('\n', yaml.find("plant: ")) - yaml.find("plant: "), "plant: " + plant.string());
    const auto r = run_command("timeout 30 " + hilbench() + " sim " + s.root.write("cfg/c.yaml", yaml).string() + " --out " +
                               s.out.string() + " --quiet");
    EXPECT_EQ(r.status, 1) << plant << "\n" << r.output;  // 124 would be the timeout: a hang
    EXPECT_NE(r.output.find("c.yaml:2:1: plant:"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(why), std::string::npos) << r.output;
  }
}

TEST(SimHostileInput, AKilledOrFailedSimLeavesNoHalfMadeFolder) {
  Sandbox s;
  // A long campaign, killed with SIGTERM while it runs: nothing of it stays.
  const auto [pid, tmp, started] = s.start_long_sim(0);
  ASSERT_TRUE(started) << "the sim did not start writing";
  kill(pid, SIGTERM);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 128 + SIGTERM) << status;
  EXPECT_FALSE(std::filesystem::exists(tmp));
  EXPECT_FALSE(std::filesystem::exists(s.out / "long"));

  // A folder left by a process that no longer exists (kill -9) is cleared by the next sim.
  const auto stale = s.out / ".x.tmp-999999999";
  std::filesystem::create_directories(stale / "none");
  const auto r = s.sim(campaign_yaml("name: x"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_FALSE(std::filesystem::exists(stale));
  EXPECT_TRUE(std::filesystem::exists(s.out / "x" / "report.html"));
  EXPECT_TRUE(std::filesystem::exists(s.out / "old" / "keep.txt"));
  EXPECT_TRUE(std::filesystem::exists(s.root.path() / "precious.txt"));
}

// A sim's unpublished folder belongs to a live process when its lock is held, whatever its PID
// says: a sim in another PID namespace (a container, another host on the same storage) has a PID
// this one cannot see, and the next sim of the campaign deleted its folder under it (it then
// failed "cannot write .../summary.json"). A folder whose lock nobody holds is a leftover.
TEST(SimHostileInput, AnUnpublishedFolderWhoseLockIsHeldIsNotTakenForALeftover) {
  Sandbox s;
  const pid_t gone = fork();  // a PID that is not alive here, as another namespace's is
  if (gone == 0) _exit(0);
  ASSERT_EQ(waitpid(gone, nullptr, 0), gone);
  const auto working = s.out / (".x.tmp-" + std::to_string(gone));
  std::filesystem::create_directories(working / "none");
  std::optional<hil::FileLock> held(std::in_place, s.out / (".x.tmp-" + std::to_string(gone) + ".lock"));
  auto r = s.sim(campaign_yaml("name: x"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(working / "none"));
  EXPECT_TRUE(std::filesystem::exists(s.out / "x" / "report.html"));
  // Its process ended without cleaning up: the next sim clears the folder and its lock file.
  held.reset();
  r = s.sim(campaign_yaml("name: x"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_FALSE(std::filesystem::exists(working));
  EXPECT_FALSE(std::filesystem::exists(s.out / (".x.tmp-" + std::to_string(gone) + ".lock")));
  // The second sim replaced the first one's result in place: one whole folder, no leftovers.
  EXPECT_TRUE(std::filesystem::exists(s.out / "x" / "none" / "summary.json"));
  for (const auto& e : std::filesystem::directory_iterator(s.out))
    EXPECT_TRUE(e.path().filename() == "x" || e.path().filename() == "old") << e.path();
}

// A second Ctrl-C ends the process at once (for work that cannot poll the first): exit 130 either
// way. Whatever it leaves of the unpublished folder holds only whole lines, nothing is published,
// and the campaign's next sim clears the leftover (its process is gone). Standard signals do not queue, so
// the two are sent 2 ms apart: the second lands while the first's stop is under way.
TEST(SimHostileInput, ASecondCtrlCLeavesOnlyWholeLinesAndTheNextSimClearsThem) {
  Sandbox s;
  const auto [pid, tmp, started] = s.start_long_sim(100000);
  ASSERT_TRUE(started) << "the sim did not start writing";
  kill(pid, SIGINT);
  std::this_thread::sleep_for(std::chrono::milliseconds(2));
  kill(pid, SIGINT);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 128 + SIGINT) << status;
  EXPECT_FALSE(std::filesystem::exists(s.out / "long"));
  if (std::filesystem::exists(tmp)) {
    for (const auto& e : std::filesystem::recursive_directory_iterator(tmp)) {
      if (!e.is_regular_file() || e.file_size() == 0) continue;
      std::ifstream in(e.path(), std::ios::binary);
      in.seekg(-1, std::ios::end);
      EXPECT_EQ(in.get(), '\n') << e.path() << " ends part way through a line";
    }
  }
  const auto r = s.sim(campaign_yaml("name: long"), "long.yaml");  // the same campaign, now 1 s long
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_FALSE(std::filesystem::exists(tmp));
  EXPECT_TRUE(std::filesystem::exists(s.out / "long" / "report.html"));
  EXPECT_TRUE(std::filesystem::exists(s.out / "old" / "keep.txt"));
}

// --runs is a choice of the campaign's runs: a name it does not have is refused with the names it
// has (none,adaptiv ran only none), and so is a list that names none ('' and ',' ran them all) or
// has an empty name (adaptive,,none: a script's empty variable).
TEST(SimHostileInput, RunsTheCampaignDoesNotHaveOrNoRunAtAllAreRefused) {
  Sandbox s;
  const auto file = s.root.write("cfg/c.yaml", campaign_yaml("name: two", "",
                                                             "  - {name: none, compensation: none}\n"
                                                             "  - {name: adaptive, compensation: adaptive}\n"));
  const auto sim = [&](const std::string& runs) {
    return run_command(hilbench() + " sim " + file.string() + " --out " + s.out.string() + " --quiet --runs " + runs);
  };
  struct Case {
    std::string runs, expect;
  };
  const Case cases[] = {
      {"none,adaptiv", "--runs: campaign 'two' has no run 'adaptiv' (did you mean 'adaptive'?); its runs are none, adaptive"},
      {"xyzzy,adaptiv", "has no run 'xyzzy', 'adaptiv' (did you mean 'adaptive'?); its runs are none, adaptive"},
      {"''",
       "--runs '' names no run: name at least one, or leave --runs out to run them all; the runs of campaign 'two' are "
       "none, adaptive"},
      {",", "--runs ',' names no run"},
      {"none,none", "--runs names 'none' twice"},
      {"adaptive,,none", "--runs 'adaptive,,none' has an empty name between its commas"},
      {"adaptive,", "--runs 'adaptive,' has an empty name between its commas"},
  };
  for (const auto& c : cases) {
    const auto r = sim(c.runs);
    EXPECT_EQ(r.status, 2) << c.runs << "\n" << r.output;
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.runs << "\nwant: " << c.expect << "\ngot: " << r.output;
    EXPECT_EQ(tree(s.out).size(), 2u) << c.runs;  // old/ and old/keep.txt: nothing ran
  }
  const auto r = sim("adaptive");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(s.out / "two" / "adaptive" / "summary.json"));
  EXPECT_FALSE(std::filesystem::exists(s.out / "two" / "none"));
}

// The campaign's name picks the folder under --out that a sim replaces: a former sim's output
// goes, anything else stays and the sim says so before it runs (a campaign named `src` with
// --out . wiped ./src).
TEST(SimHostileInput, AFolderOrFileTheSimDidNotWriteIsNotReplaced) {
  Sandbox s;
  auto r = s.sim(campaign_yaml("name: old"));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("keep.txt, which hilbench sim does not write"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("choose another --out"), std::string::npos) << r.output;
  EXPECT_TRUE(std::filesystem::exists(s.out / "old" / "keep.txt"));

  s.root.write("out/afile", "a file, not a folder\n");
  r = s.sim(campaign_yaml("name: afile"));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("afile exists and is not a folder"), std::string::npos) << r.output;
  EXPECT_TRUE(std::filesystem::is_regular_file(s.out / "afile"));

  // A former sim's output is replaced, the second time too; a note put in it stops the third.
  ASSERT_EQ(s.sim(campaign_yaml("name: x")).status, 0);
  r = s.sim(campaign_yaml("name: x"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(s.out / "x" / "none" / "summary.json"));
  s.root.write("out/x/none/notes.md", "what I saw\n");
  r = s.sim(campaign_yaml("name: x"));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("notes.md"), std::string::npos) << r.output;
  EXPECT_TRUE(std::filesystem::exists(s.out / "x" / "none" / "notes.md"));
  EXPECT_TRUE(std::filesystem::exists(s.root.path() / "precious.txt"));
}

}  // namespace
