// JUnit XML of campaign verdicts, as Jenkins, GitLab and GitHub read it: <testsuites> of one
// <testsuite> per campaign, a <testcase> per run and check (classname "campaign.run"), <failure>
// with the measured value and its limit, <error> for a run that did not complete (and its checks
// never judged) or a campaign file that could not be read, <skipped> with why, and the campaign's
// report as an attachment ([[ATTACHMENT|path]] in <system-out>, the Jenkins attachments / GitLab
// convention). Only the attributes the Jenkins xUnit JUnit schema allows: <testsuites> name,
// tests, failures, errors, time (no skipped); <testsuite> those and skipped; <testcase> name,
// classname, time.
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

struct Counts {
  long tests = 0, failures = 0, errors = 0, skipped = 0;
};

// <testcase ...> with `inner` (what it holds), counted.
std::string testcase(const std::string& classname, const std::string& name, double time_s, const std::string& inner) {
  const std::string head =
      "    <testcase classname=\"" + xml(classname) + "\" name=\"" + xml(name) + "\" time=\"" + seconds(time_s) + "\"";
  return inner.empty() ? head + "/>\n" : head + ">\n" + inner + "    </testcase>\n";
}

std::string outcome_tag(const char* tag, const std::string& type, const std::string& message) {
  return "      <" + std::string(tag) + " type=\"" + xml(type) + "\" message=\"" + xml(message) + "\">" + xml(message) + "</" +
         tag + ">\n";
}

std::string system_out(const std::string& text, const std::string& report_path) {
  std::string t = text;
  if (!report_path.empty()) {
    if (!t.empty()) t += '\n';
    t.append("[[ATTACHMENT|").append(report_path).append("]]");
  }
  return t.empty() ? "" : "      <system-out>" + xml(t) + "</system-out>\n";
}

// A run's testcases: "completed" when it has no checks or did not complete, then one per check.
std::string run_cases(const JunitSuite& suite, const JunitRun& run, Counts& n) {
  const std::string classname = suite.campaign + "." + run.name;
  const bool completed = run.outcome == "completed";
  const std::string ended = "run " + run.name + " " + run.outcome + (run.reason.empty() ? "" : ": " + run.reason);
  std::string cases;
  if (!completed || run.results.empty()) {
    ++n.tests;
    std::string inner;
    if (!completed) {
      ++n.errors;
      inner = outcome_tag("error", run.outcome, ended) + system_out(ended, suite.report_path);
    }
    cases += testcase(classname, "completed", run.wall_s, inner);
  }
  for (const auto& r : run.results) {
    ++n.tests;
    std::string inner;
    if (r.verdict == Verdict::fail) {
      ++n.failures;
      inner = outcome_tag("failure", "threshold", r.message);
    } else if (r.verdict == Verdict::skipped && !completed) {
      ++n.errors;  // never judged: the run ended first
      inner = outcome_tag("error", "not judged", "not judged, the " + ended + (r.message.empty() ? "" : " (" + r.message + ")"));
    } else if (r.verdict == Verdict::skipped) {
      ++n.skipped;
      inner = "      <skipped message=\"" + xml(r.message) + "\"/>\n";
    }
    cases += testcase(classname, r.check, run.wall_s, inner + system_out(r.message, suite.report_path));
  }
  return cases;
}

}  // namespace

std::string junit_xml(const std::vector<JunitSuite>& suites) {
  Counts all;
  double all_time = 0;
  std::string body;
  for (const auto& suite : suites) {
    Counts n;
    std::string cases;
    if (!suite.error.empty()) {
      ++n.tests, ++n.errors;
      cases = testcase(suite.campaign, "campaign file", 0, outcome_tag("error", "configuration", suite.error));
    }
    for (const auto& run : suite.runs) cases += run_cases(suite, run, n);
    body += "  <testsuite name=\"" + xml(suite.campaign) + "\" tests=\"" + std::to_string(n.tests) + "\" failures=\"" +
            std::to_string(n.failures) + "\" errors=\"" + std::to_string(n.errors) + "\" skipped=\"" + std::to_string(n.skipped) +
            "\" time=\"" + seconds(suite.wall_s) + "\">\n" + cases;
    if (!suite.report_path.empty())
      body += "    <system-out>" + xml("[[ATTACHMENT|" + suite.report_path + "]]") + "</system-out>\n";
    body += "  </testsuite>\n";
    all.tests += n.tests, all.failures += n.failures, all.errors += n.errors;
    all_time += suite.wall_s;
  }
  return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites name=\"hilbench\" tests=\"" + std::to_string(all.tests) +
         "\" failures=\"" + std::to_string(all.failures) + "\" errors=\"" + std::to_string(all.errors) + "\" time=\"" +
         seconds(all_time) + "\">\n" + body + "</testsuites>\n";
}

}  // namespace hil::bench
