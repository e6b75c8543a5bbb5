// What the tool writes where a user names a file, against the real binary: every writer (sim's
// and run's --junit, report's --out, diagnose's --write-model and --out, compare's --out)
// creates a new file or replaces one it wrote, and refuses the campaign it reads, a file of
// another kind, a FIFO, a symbolic link and a device, leaving each as it was. And CI's verdict
// never goes missing: a broken campaign file among good ones is an <error> testcase naming
// file:line in the JUnit XML, which is still written (exit 1), the good campaigns run, and the
// attachments may be relative to the workspace.
#include <sys/stat.h>

#include <gtest/gtest.h>

#include <functional>
#include <string>
#include <vector>

#include "support/run_command.hpp"
#include "support/temp_file.hpp"

using hil::test::hilbench;
using hil::test::run_command;
using hil::test::slurp;
using hil::test::source_path;
namespace fs = std::filesystem;

namespace {

std::string q(const fs::path& p) { return "'" + p.string() + "'"; }

fs::path small_campaign(const hil::test::TempDir& dir, const std::string& name, const std::string& duration_s = "0.3") {
  return dir.write(name + ".yaml", "name: " + name + "\nplant: " + source_path("configs/plant/nominal.yaml").string() +
                                       "\nduration_s: " + duration_s +
                                       "\nperiod_ms: 1\nseed: 3\nreference:\n  initial_mpa: 1.0\n"
                                       "gap:\n  initial_deg: 1.0\nruns:\n  - {name: none, compensation: none}\n"
                                       "checks:\n  - {name: no_safe_state, signal: safe_state, max: 0}\n");
}

std::string schema_problems(const fs::path& file) {
  const auto r = run_command("/usr/bin/python3 " + q(source_path("tests/support/junit_schema_check.py")) + " " + q(file));
  return r.status == 0 ? "" : r.output;
}

TEST(CiVerdicts, ABrokenCampaignAmongGoodOnesIsAnErrorInTheJunitThatIsStillWritten) {
  hil::test::TempDir dir;
  const auto good = small_campaign(dir, "good", "5");  // a few ms of wall time: its cases' time is not 0.000
  std::string text = slurp(source_path("configs/campaigns/paper_fig6.yaml"));
  text.replace(text.find("high_mpa: 1.5"), 13, "high_mpa: 9.0");
  text.replace(text.find("../plant/nominal.yaml"), 21, source_path("configs/plant/nominal.yaml").string());
  const auto broken = dir.write("broken.yaml", text);
  const auto junit = dir.path() / "ci" / "junit.xml";
  const auto out = dir.path() / "out";
  // From the workspace, as a CI job runs it: the attachment relative to it.
  const auto r = run_command("cd " + q(dir.path()) + " && " + hilbench() + " sim " + q(good) + " " + q(broken) +
                             " --quiet --no-telemetry --out out --junit " + q(junit) + " --junit-relative");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("1 campaign file(s) could not be read"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(out / "good" / "report.html")) << "the good campaign ran";
  ASSERT_TRUE(fs::exists(junit)) << r.output;
  const std::string xml = slurp(junit);
  EXPECT_EQ(schema_problems(junit), "") << xml;
  EXPECT_NE(xml.find("<testsuite name=\"" + broken.string() + "\" tests=\"1\" failures=\"0\" errors=\"1\""), std::string::npos)
      << xml;
  EXPECT_NE(xml.find("name=\"campaign file\" time=\"0.000\">\n      <error type=\"configuration\" message=\"" + broken.string() +
                     ":14:"),
            std::string::npos)
      << xml;
  EXPECT_NE(xml.find("high_mpa"), std::string::npos) << xml;
  EXPECT_NE(xml.find("<testsuite name=\"good\" tests=\"1\" failures=\"0\" errors=\"0\""), std::string::npos) << xml;
  EXPECT_NE(xml.find("[[ATTACHMENT|out/good/report.html]]"), std::string::npos) << xml;
  EXPECT_NE(xml.find("<testsuites name=\"hilbench\" tests=\"2\" failures=\"0\" errors=\"1\" time=\""), std::string::npos) << xml;
  EXPECT_EQ(xml.find("classname=\"good.none\" name=\"no_safe_state\" time=\"0.000\""), std::string::npos)
      << "the case has its run's time\n"
      << xml;

  // A second sim replaces the JUnit XML it wrote.
  const auto again =
      run_command(hilbench() + " sim " + q(good) + " --quiet --no-telemetry --out " + q(out) + " --junit " + q(junit));
  EXPECT_EQ(again.status, 0) << again.output;
  EXPECT_EQ(slurp(junit).find("broken"), std::string::npos);
}

struct Writer {
  std::string name;
  std::function<std::string(const fs::path& target)> command;
  std::string option;
};

// Each writer against each path it must not replace: refused naming the option and why, the
// path left as it was.
TEST(OutputPaths, NoWriterReplacesAnInputAFileOfAnotherKindAFifoALinkOrADevice) {
  hil::test::TempDir dir;
  const auto campaign = small_campaign(dir, "paths");
  const auto runs = dir.path() / "runs";
  ASSERT_EQ(run_command(hilbench() + " run " + q(campaign) + " --rig sim --configs " + q(source_path("configs")) + " --out " +
                        q(runs) + " --speed 10 --no-mlock --quiet")
                .status,
            0);
  fs::path run;
  for (const auto& e : fs::directory_iterator(runs))
    if (e.is_directory()) run = e.path();
  ASSERT_FALSE(run.empty());
  const auto sim_out = dir.path() / "out";
  ASSERT_EQ(run_command(hilbench() + " sim " + q(campaign) + " --quiet --no-telemetry --out " + q(sim_out)).status, 0);
  const auto report = sim_out / "paths" / "report.html";  // a report the tool wrote: not JUnit XML
  const auto fifo = dir.path() / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
  const auto link = dir.path() / "link.xml";
  fs::create_symlink(dir.path() / "elsewhere.xml", link);
  const auto model = source_path("configs/plant/nominal.yaml").string();
  const std::string data = (run / "telemetry.csv").string();
  const std::vector<Writer> writers = {
      {"sim --junit",
       [&](const fs::path& t) {
         return " sim " + q(campaign) + " --quiet --no-telemetry --out " + q(sim_out) + " --junit " + q(t);
       },
       "--junit"},
      {"run --junit",
       [&](const fs::path& t) {
         return " run " + q(campaign) + " --rig sim --configs " + q(source_path("configs")) + " --out " + q(runs) +
                " --speed 10 --no-mlock --quiet --junit " + q(t);
       },
       "--junit"},
      {"report --out", [&](const fs::path& t) { return " report " + q(run) + " --quiet --out " + q(t); }, "--out"},
      {"diagnose --write-model",
       [&](const fs::path& t) {
         return " diagnose --model " + model + " --data " + data + " --out " + q(dir.path() / "d") + " --write-model " + q(t);
       },
       "--write-model"},
  };
  struct Target {
    fs::path path;
    std::string why;
  };
  const std::vector<Target> targets = {
      {campaign, ""},  // an input (sim, run) or a file the tool did not write as that output (report, model)
      {report, ""},    // a file of another kind (JUnit, model) or... the report itself: see below
      {fifo, "is a FIFO"},
      {link, "is a symbolic link to " + (dir.path() / "elsewhere.xml").string()},
      {"/dev/full", "is a character device"},
  };
  const std::string campaign_text = slurp(campaign), report_text = slurp(report);
  for (const auto& w : writers) {
    for (const auto& t : targets) {
      if (w.name == "report --out" && t.path == report) continue;  // a report replaces a report
      SCOPED_TRACE(w.name + " onto " + t.path.string());
      const auto r = run_command(hilbench() + w.command(t.path));
      EXPECT_EQ(r.status, 1) << r.output;
      EXPECT_NE(r.output.find(w.option + " " + t.path.string() + ": "), std::string::npos) << r.output;
      if (!t.why.empty()) {
        EXPECT_NE(r.output.find(t.why), std::string::npos) << r.output;
      }
    }
  }
  EXPECT_TRUE(slurp(campaign) == campaign_text) << "the campaign was replaced";
  EXPECT_TRUE(slurp(report) == report_text) << "the report was replaced";
  EXPECT_EQ(fs::symlink_status(fifo).type(), fs::file_type::fifo);
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_FALSE(fs::exists(dir.path() / "elsewhere.xml"));
  EXPECT_EQ(fs::symlink_status("/dev/full").type(), fs::file_type::character);
  EXPECT_FALSE(fs::exists(dir.path() / "d")) << "refused before the fit";

  // compare's and diagnose's --out DIR: a FIFO where report.html goes is refused too.
  const auto cmp = dir.path() / "cmp";
  fs::create_directories(cmp);
  ASSERT_EQ(::mkfifo((cmp / "report.html").c_str(), 0644), 0);
  for (const char* cmd : {"compare", "diagnose"}) {
    const auto r = run_command(hilbench() + " " + cmd + " --model " + model + " --data " + data + " --out " + q(cmp));
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find("--out " + (cmp / "report.html").string() + ": is a FIFO"), std::string::npos) << r.output;
  }
}

}  // namespace
