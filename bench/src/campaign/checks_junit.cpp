// JUnit XML of campaign verdicts, as Jenkins, GitLab and GitHub read it: <testsuites> of one
// <testsuite> per campaign, a <testcase> per run and check (classname "campaign.run"), <failure>
// with the measured value and its limit, <skipped> with why, and the campaign's report as an
// attachment ([[ATTACHMENT|path]] in <system-out>, the Jenkins attachments / GitLab convention).
#include <cstdio>
#include <string>

#include "hil/bench/campaign/checks.hpp"

namespace hil::bench {
namespace {

// Text and attribute values: the five XML specials escaped, and characters XML 1.0 cannot hold
// at all (controls other than tab, newline, return) replaced, so any name or message stays XML.
std::string xml(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    switch (ch) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      case '\t': out += "&#9;"; break;
      case '\n': out += "&#10;"; break;
      case '\r': out += "&#13;"; break;
      default: out += c < 0x20 || c == 0x7f ? '?' : ch;
    }
  }
  return out;
}

std::string seconds(double s) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3f", s > 0 ? s : 0.0);
  return b;
}

}  // namespace

std::string junit_xml(const std::vector<JunitSuite>& suites) {
  long all_tests = 0, all_failures = 0, all_skipped = 0;
  double all_time = 0;
  std::string body;
  for (const auto& suite : suites) {
    long tests = 0, failures = 0, skipped = 0;
    std::string cases;
    for (const auto& run : suite.runs) {
      const std::string classname = xml(suite.campaign + "." + run.name);
      if (run.results.empty()) {
        ++tests;
        cases += "    <testcase classname=\"" + classname + "\" name=\"completed\" time=\"" + seconds(run.wall_s) + "\"/>\n";
        continue;
      }
      for (const auto& r : run.results) {
        ++tests;
        cases += "    <testcase classname=\"" + classname + "\" name=\"" + xml(r.check) + "\" time=\"0\">\n";
        if (r.verdict == Verdict::fail) {
          ++failures;
          cases += "      <failure type=\"threshold\" message=\"" + xml(r.message) + "\">" + xml(r.message) + "</failure>\n";
        } else if (r.verdict == Verdict::skipped) {
          ++skipped;
          cases += "      <skipped message=\"" + xml(r.message) + "\"/>\n";
        }
        cases += "      <system-out>" + xml(r.message);
        if (!suite.report_path.empty()) cases += xml("\n[[ATTACHMENT|" + suite.report_path + "]]");
        cases += "</system-out>\n    </testcase>\n";
      }
    }
    body += "  <testsuite name=\"" + xml(suite.campaign) + "\" tests=\"" + std::to_string(tests) + "\" failures=\"" +
            std::to_string(failures) + "\" errors=\"0\" skipped=\"" + std::to_string(skipped) + "\" time=\"" +
            seconds(suite.wall_s) + "\">\n" + cases;
    if (!suite.report_path.empty())
      body += "    <system-out>" + xml("[[ATTACHMENT|" + suite.report_path + "]]") + "</system-out>\n";
    body += "  </testsuite>\n";
    all_tests += tests;
    all_failures += failures;
    all_skipped += skipped;
    all_time += suite.wall_s;
  }
  return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites name=\"hilbench\" tests=\"" + std::to_string(all_tests) +
         "\" failures=\"" + std::to_string(all_failures) + "\" errors=\"0\" skipped=\"" + std::to_string(all_skipped) +
         "\" time=\"" + seconds(all_time) + "\">\n" + body + "</testsuites>\n";
}

}  // namespace hil::bench
