// The campaign report opens offline in headless Chromium and every plot renders.
#include <gtest/gtest.h>

#include "report/browser_check.hpp"
#include "support/run_command.hpp"
#include "support/temp_file.hpp"

TEST(SimReport, RendersInChromium) {
  hil::test::TempDir out;
  const auto r = hil::test::run_command(hil::test::hilbench() + " sim " +
                                        hil::test::source_path("configs/campaigns/paper_adaptive.yaml").string() +
                                        " --no-telemetry --quiet --out " + out.path().string());
  ASSERT_EQ(r.status, 0) << r.output;
  const auto result = hil::test::check_report_in_chromium(out.path() / "paper_adaptive" / "report.html");
  ASSERT_TRUE(result.error.empty()) << result.error;
  EXPECT_EQ(result.plot_errors, 0) << result.first_error;
  EXPECT_GE(result.plots, 14);  // overlay + 4 rows x 3 runs + the stall bars
  EXPECT_GT(result.min_ink, 0);
}
