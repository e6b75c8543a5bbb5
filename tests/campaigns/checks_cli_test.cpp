// `hilbench sim ... --junit FILE` as a CI job runs it: the shipped campaigns' checks pass on the
// simulated plant, a campaign whose check is set to fail exits non-zero, and the JUnit XML is
// read by a real consumer, Debian's python3-junitparser, with the right counts.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <vector>
#include <string>

#include "hil/bench/campaign/checks.hpp"
#include "support/run_command.hpp"
#include "support/temp_file.hpp"

using hil::test::hilbench;
using hil::test::run_command;
using hil::test::slurp;
using hil::test::source_path;

namespace {

std::string q(const std::filesystem::path& p) { return "'" + p.string() + "'"; }

// What junitparser reads from a JUnit file: per suite its name and counts, per case its class,
// name, result and message, and the suites' system-out. Debian's python3 (the package's).
nlohmann::json junitparser_reads(const hil::test::TempDir& dir, const std::filesystem::path& xml) {
  const auto script = dir.write("read_junit.py", R"(import json, sys
from junitparser import JUnitXml, TestSuite, Failure, Skipped
xml = JUnitXml.fromfile(sys.argv[1])
suites = [xml] if isinstance(xml, TestSuite) else list(xml)
out = []
for s in suites:
    cases = []
    for c in s:
        kinds = [type(r).__name__ for r in c.result]
        cases.append({"classname": c.classname, "name": c.name, "results": kinds,
                      "message": c.result[0].message if c.result else None, "system_out": c.system_out})
    out.append({"name": s.name, "tests": s.tests, "failures": s.failures, "errors": s.errors, "skipped": s.skipped,
                "cases": cases, "system_out": "".join(e.text or "" for e in s._elem.findall("system-out"))})
print(json.dumps(out))
)");
  const auto r = run_command("/usr/bin/python3 " + q(script) + " " + q(xml));
  EXPECT_EQ(r.status, 0) << r.output;
  try {
    return nlohmann::json::parse(r.output);
  } catch (const std::exception& e) {
    ADD_FAILURE() << e.what() << ": " << r.output;
    return nlohmann::json::array();
  }
}

// A shipped campaign, its plant path made absolute, written into `dir` with `edit` applied.
std::filesystem::path campaign_copy(const hil::test::TempDir& dir, const std::string& name,
                                    const std::function<std::string(std::string)>& edit) {
  std::string text = slurp(source_path("configs/campaigns/" + name + ".yaml"));
  text = std::regex_replace(text, std::regex("plant: \\.\\./plant/"), "plant: " + source_path("configs/plant").string() + "/");
  return dir.write(name + ".yaml", edit(text));
}

TEST(ChecksCli, ShippedCampaignsPassAndJunitParserReadsTheCounts) {
  hil::test::TempDir dir;
  const auto out = dir.path() / "out";
  const auto xml = dir.path() / "ci" / "junit.xml";
  const auto r =
      run_command(hilbench() + " sim " + q(source_path("configs/campaigns/paper_adaptive.yaml")) + " " +
                  q(source_path("configs/campaigns/gap_shrink.yaml")) + " --no-telemetry --out " + q(out) + " --junit " + q(xml));
  ASSERT_EQ(r.status, 0) << r.output;
  const auto suites = junitparser_reads(dir, xml);
  ASSERT_EQ(suites.size(), 2u) << suites.dump();
  for (const auto& s : suites) {
    const std::string campaign = s["name"];
    const auto summary = [&](const std::string& run) {
      return nlohmann::json::parse(slurp(out / campaign / run / "summary.json"));
    };
    long tests = 0;
    for (const char* run : {"none", "adaptive", "adaptive_paper"}) {
      const auto checks = summary(run)["checks"];
      const long n = checks["passed"].get<long>() + checks["failed"].get<long>() + checks["skipped"].get<long>();
      tests += n == 0 ? 1 : n;  // a run without checks is one case, "completed"
      EXPECT_EQ(checks["failed"], 0) << campaign << "/" << run << ": " << checks.dump(1);
    }
    EXPECT_GT(tests, 3) << campaign;  // the claims are there, not only "completed"
    EXPECT_EQ(s["tests"], tests) << campaign;
    EXPECT_EQ(s["failures"], 0);
    EXPECT_EQ(s["errors"], 0);
    // Each case: class campaign.run, the report as an attachment.
    const std::string attachment = "[[ATTACHMENT|" + (out / campaign / "report.html").string() + "]]";
    for (const auto& c : s["cases"]) {
      EXPECT_EQ(c["classname"].get<std::string>().rfind(campaign + ".", 0), 0u) << c.dump();
      EXPECT_NE(c["system_out"].get<std::string>().find(attachment), std::string::npos) << c.dump();
    }
  }
}

TEST(ChecksCli, ACheckSetToFailExitsNonZeroWithValueAndLimit) {
  hil::test::TempDir dir;
  // paper_fig6 (one run, none): a stall of at most 1 ms per reversal, which it cannot meet.
  const auto failing = campaign_copy(dir, "paper_fig6", [](std::string t) {
    const auto at = t.find("\nchecks:");
    if (at != std::string::npos) t.resize(at + 1);
    return t +
           "checks:\n"
           "  - {name: no_stall, metric: stall_s_per_reversal, reduce: max, max: 0.001}\n"
           "  - {name: no_trips, metric: interlock_trips, max: 0}\n";
  });
  const auto xml = dir.path() / "junit.xml";
  const auto r = run_command(hilbench() + " sim " + q(failing) + " --no-telemetry --quiet --out " + q(dir.path() / "out") +
                             " --junit " + q(xml));
  EXPECT_EQ(r.status, 3) << r.output;
  EXPECT_NE(r.output.find("fail    none/no_stall: stall_s_per_reversal = "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("1 check(s) failed"), std::string::npos) << r.output;
  const auto suites = junitparser_reads(dir, xml);
  ASSERT_EQ(suites.size(), 1u);
  EXPECT_EQ(suites[0]["name"], "paper_fig6");
  EXPECT_EQ(suites[0]["tests"], 2);
  EXPECT_EQ(suites[0]["failures"], 1);
  for (const auto& c : suites[0]["cases"]) {
    if (c["name"] != "no_stall") {
      EXPECT_TRUE(c["results"].empty()) << c.dump();
      continue;
    }
    ASSERT_EQ(c["results"], nlohmann::json::array({"Failure"})) << c.dump();
    const std::string message = c["message"];
    EXPECT_TRUE(std::regex_search(message, std::regex("stall_s_per_reversal = [0-9.]+ > max 0\\.001"))) << message;
  }
}

// A sweep point is its campaign run by `hilbench sim`'s code: a check of the campaign that fails
// fails the point, with no threshold in the sweep file. paper_fig6's stall per reversal grows with
// the gap: 0.13 s at 0.2 deg, 0.78 s at 2 deg, against a limit of 0.5 s.
TEST(ChecksCli, AFailedCheckIsAFailedSweepPoint) {
  hil::test::TempDir dir;
  campaign_copy(dir, "paper_fig6", [](std::string t) {
    t.resize(t.find("\nchecks:") + 1);
    return t + "checks:\n  - {name: small_stall, metric: stall_s_per_reversal, max: 0.5}\n";
  });
  const auto sweep = dir.write("gaps.yaml",
                               "name: gaps\ncampaign: paper_fig6.yaml\naxes:\n"
                               "  - path: campaign.gap.initial_deg\n    values: [0.2, 2]\n");
  const auto r = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(dir.path() / "out") + " --jobs 1");
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string csv = slurp(dir.path() / "out" / "sweep.csv");
  const auto lines = [&] {
    std::vector<std::string> out;
    std::stringstream in(csv);
    for (std::string line; std::getline(in, line);) out.push_back(line);
    return out;
  }();
  ASSERT_EQ(lines.size(), 3u) << csv;
  EXPECT_NE(lines[0].find(",none.checks_failed,pass"), std::string::npos) << lines[0];
  EXPECT_EQ(lines[1].substr(0, 6), "0,0.2,");
  EXPECT_EQ(lines[1].substr(lines[1].size() - 7), ",0,pass") << lines[1];
  EXPECT_EQ(lines[2].substr(0, 4), "1,2,");
  EXPECT_EQ(lines[2].substr(lines[2].size() - 7), ",1,fail") << lines[2];
  // The report's worst points say why the point fails.
  EXPECT_NE(slurp(dir.path() / "out" / "report.html").find("none: 1 checks failed"), std::string::npos);
}

// A sweep map's cells each stand for several points (here 2 seeds); the report counts how many of
// them fail for the map's run (its checks), per cell: all at a 2 deg gap (stall about 0.78 s > 0.5 s), none at 0.2 deg.
TEST(ChecksCli, SweepMapCountsFailingPointsPerCell) {
  hil::test::TempDir dir;
  campaign_copy(dir, "paper_fig6", [](std::string t) {
    t.resize(t.find("\nchecks:") + 1);
    return t + "checks:\n  - {name: small_stall, metric: stall_s_per_reversal, max: 0.5}\n";
  });
  const auto sweep =
      dir.write("gaps.yaml",
                "name: gaps\ncampaign: paper_fig6.yaml\naxes:\n"
                "  - {path: campaign.gap.initial_deg, values: [0.2, 2]}\n"
                "  - {path: campaign.sensor_noise_kpa, values: [0, 1]}\n"
                "  - {path: campaign.seed, values: [1, 2]}\n"
                "maps:\n"
                "  - {metric: none.stall_s_per_reversal, x: campaign.gap.initial_deg, y: campaign.sensor_noise_kpa}\n");
  const auto r = run_command(hilbench() + " sweep " + q(sweep) + " --out " + q(dir.path() / "out") + " --jobs 1");
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string html = slurp(dir.path() / "out" / "report.html");
  const auto count = [&](const std::string& what) {
    long n = 0;
    for (auto at = html.find(what); at != std::string::npos; at = html.find(what, at + 1)) ++n;
    return n;
  };
  EXPECT_EQ(count("fail for the run none ("), 1);
  EXPECT_EQ(count(">2 of 2 fail<"), 2) << "the 2 deg column, both noises";
  EXPECT_EQ(count(">0 of 2 fail<"), 2) << "the 0.2 deg column, both noises";
}

// Names and messages with every character XML reserves, and controls XML 1.0 cannot hold, stay one
// well-formed document with the text as it was.
TEST(ChecksCli, JunitEscapesEverything) {
  hil::test::TempDir dir;
  hil::bench::CheckResult failed;
  failed.check = "a<b>&\"c'";
  failed.run = "r";
  failed.verdict = hil::bench::Verdict::fail;
  failed.message = "x < 1 & y > \"2\" 'z'\x01";
  hil::bench::CheckResult skipped = failed;
  skipped.check = "s";
  skipped.verdict = hil::bench::Verdict::skipped;
  const std::string text =
      hil::bench::junit_xml({{"camp]]>aign", "/tmp/r&d/report.html", 1.5, {{"r", 0.5, {failed, skipped}}, {"quiet", 0.1, {}}}}});
  const auto suites = junitparser_reads(dir, dir.write("j.xml", text));
  ASSERT_EQ(suites.size(), 1u);
  EXPECT_EQ(suites[0]["name"], "camp]]>aign");
  EXPECT_EQ(suites[0]["tests"], 3);
  EXPECT_EQ(suites[0]["failures"], 1);
  EXPECT_EQ(suites[0]["skipped"], 1);
  const auto& cases = suites[0]["cases"];
  ASSERT_EQ(cases.size(), 3u);
  EXPECT_EQ(cases[0]["name"], "a<b>&\"c'");
  EXPECT_EQ(cases[0]["message"], "x < 1 & y > \"2\" 'z'?");
  EXPECT_EQ(cases[1]["results"], nlohmann::json::array({"Skipped"}));
  EXPECT_EQ(cases[2]["name"], "completed");  // a run without checks: it ran
  EXPECT_NE(suites[0]["system_out"].get<std::string>().find("[[ATTACHMENT|/tmp/r&d/report.html]]"), std::string::npos);
}

}  // namespace
