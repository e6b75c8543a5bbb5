// The paper's and the robust observer became registered compensators without changing a bit of
// what they do: `hilbench sim` on the shipped campaigns (and on robust_params.yaml, which sets
// the robust compensator's parameters at the campaign and at a run through today's keys) writes
// the telemetry.csv bytes and the summary values that the code before the change wrote
// (data/telemetry_golden.txt, recorded with it).
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "run_command.hpp"
#include "temp_file.hpp"

namespace {

using hil::test::hilbench;
using hil::test::run_command;
using hil::test::slurp;
using hil::test::source_path;
using hil::test::TempDir;

std::uint64_t fnv1a64(const std::string& bytes) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 0x100000001b3ULL;
  }
  return h;
}

TEST(TelemetryGolden, RegisteredCompensatorsWriteTheTelemetryOfBefore) {
  TempDir out;
  for (const char* campaign :
       {"configs/campaigns/paper_adaptive.yaml", "configs/campaigns/paper_constant.yaml", "configs/campaigns/paper_fig6.yaml",
        "configs/campaigns/gap_shrink.yaml", "tests/campaigns/data/robust_params.yaml"}) {
    const auto r = run_command(hilbench() + " sim " + source_path(campaign).string() + " --out " + out.path().string());
    ASSERT_EQ(r.status, 0) << campaign << ": " << r.output;
  }
  std::ifstream golden(source_path("tests/campaigns/data/telemetry_golden.txt"));
  int runs = 0;
  for (std::string line; std::getline(golden, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream in(line);
    std::string run, hash, iae, gap;
    in >> run >> hash >> iae >> gap;
    SCOPED_TRACE(run);
    char text[17];
    std::snprintf(text, sizeof text, "%016llx",
                  static_cast<unsigned long long>(fnv1a64(slurp(out.path() / run / "telemetry.csv"))));
    EXPECT_EQ(text, hash) << "telemetry.csv differs from the recorded one";
    const auto summary = nlohmann::json::parse(slurp(out.path() / run / "summary.json"));
    EXPECT_EQ(summary["iae_mpa_s"].get<double>(), std::strtod(iae.c_str(), nullptr));
    EXPECT_EQ(summary["gap_est_final_deg"].get<double>(), std::strtod(gap.c_str(), nullptr));
    ++runs;
  }
  EXPECT_EQ(runs, 14);
}

}  // namespace
