// Every route of the real `hilbench serve` that reads a file of a run folder, against each kind of
// file it must not read: a symbolic link to a file outside the runs folder, a FIFO (whose open
// blocked: the request and every later /api/runs request hung, and SIGTERM did not end the
// server), a device (a link to /dev/zero, and a character device node itself where the test runs
// as root) and a missing file. Each is answered 4xx naming the file, never its content, never a
// 500, at once; the server goes on answering and ends on SIGTERM.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <string>
#include <vector>

#include "run_folder.hpp"
#include "server_process.hpp"

namespace {

using namespace std::chrono_literals;
using hil::test::ServerProcess;
using nlohmann::json;

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

const char* const kSecret = "TOP-SECRET-RUN-FILE";

struct Case {
  std::string id, file, kind;  // the run folder, the file made hostile, how
};

// A run folder with a run.json, a telemetry.csv and an events.jsonl, then `file` made `kind`.
void make_run(const std::filesystem::path& runs, const Case& c, const std::filesystem::path& secret) {
  const auto dir = runs / c.id;
  const std::string yaml = hil::test::short_campaign_yaml(1);
  hil::test::write_ended_run(dir, "short_adaptive", "adaptive", yaml,
                             hil::test::source_path("configs/campaigns/paper_adaptive.yaml"), 1);
  std::ofstream(dir / "telemetry.csv") << "t_s,theta_cmd_deg,p_meas_mpa,theta_motor_deg,p_ref_mpa\n0,1,1,1,1\n0.5,1,1,1,1\n";
  std::ofstream(dir / "events.jsonl") << R"({"utc": "u", "t_s": 0.1, "kind": "gap_change", "gap_deg": 1})"
                                      << "\n";
  const auto path = dir / c.file;
  std::filesystem::remove(path);
  if (c.kind == "link") std::filesystem::create_symlink(secret, path);
  if (c.kind == "fifo") {
    ASSERT_EQ(::mkfifo(path.c_str(), 0600), 0);
  }
  if (c.kind == "device_link") std::filesystem::create_symlink("/dev/zero", path);
  if (c.kind == "device") {
    ASSERT_EQ(::mknod(path.c_str(), S_IFCHR | 0600, makedev(1, 5)), 0) << "mknod (as root)";
  }
}

struct Timed {
  int status = 0;
  std::string body;
  double seconds = 0;
};

Timed timed_get(const hil::bench::ApiClient& api, const std::string& target) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto r = api.get(target);
  return {r.status, r.body, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()};
}

}  // namespace

TEST(ServerRunFiles, EveryRouteRefusesALinkAFifoADeviceAndAMissingFileAtOnce) {
  hil::test::TempDir base;
  const auto secret = base.path() / "secret.txt";
  std::ofstream(secret) << kSecret << "\n";
  const auto runs = base.path() / "runs";
  std::vector<std::string> kinds = {"link", "fifo", "device_link", "missing"};
  if (::geteuid() == 0) kinds.emplace_back("device");
  std::vector<Case> cases;
  int n = 0;
  for (const std::string file : {"events.jsonl", "telemetry.csv", "run.json"}) {
    for (const auto& kind : kinds) {
      char id[64];
      std::snprintf(id, sizeof id, "20261127T05%04dZ_short_adaptive", n++);
      cases.push_back({id, file, kind});
      make_run(runs, cases.back(), secret);
    }
  }
  ServerProcess server({"--runs-dir", runs.string()});
  const auto api = server.client();

  double slowest_s = 0;
  for (const auto& c : cases) {
    const std::string what = c.file + " as " + c.kind + " (" + c.id + ")";
    const std::string run = "/api/runs/" + c.id;
    // Each route that reads the file, and the status it must answer with.
    std::vector<std::pair<std::string, std::vector<int>>> asks;
    const bool missing = c.kind == "missing";
    if (c.file == "events.jsonl") {
      asks = {{run + "/events", {missing ? 404 : 403}}, {run + "/events.jsonl", {missing ? 404 : 403}}};
    } else if (c.file == "telemetry.csv") {
      asks = {{run + "/telemetry?from_s=0&to_s=1&columns=p_meas_mpa", {missing ? 404 : 403}},
              {run + "/telemetry.csv", {missing ? 404 : 403}}};
    } else {
      // A folder without run.json is no run; one whose run.json cannot be read is named 422.
      asks = {{run, {missing ? 404 : 422}}, {run + "/run.json", {missing ? 404 : 403}}};
    }
    // A report reads all three: refused before it is queued (a missing events.jsonl or
    // telemetry.csv is a report without them, or a 422 saying what it lacks).
    asks.push_back({run + "/report.html?wait=0", {missing ? 202 : 422, 200, 404, 422}});
    for (const auto& [target, statuses] : asks) {
      const Timed r = timed_get(api, target);
      slowest_s = std::max(slowest_s, r.seconds);
      EXPECT_NE(std::find(statuses.begin(), statuses.end(), r.status), statuses.end())
          << what << ": GET " << target << " -> " << r.status << " " << r.body;
      EXPECT_LT(r.status, 500) << what << ": GET " << target << " " << r.body;
      EXPECT_FALSE(has(r.body, kSecret)) << what << ": GET " << target;
      // A refusal names the file (its path in the run folder), so the operator knows which one.
      if (r.status == 403 || r.status == 404) {
        EXPECT_TRUE(has(r.body, c.file) || has(r.body, c.id)) << what << ": " << r.body;
      }
      // A FIFO was never answered: within a second now (a regular file's request takes milliseconds).
      EXPECT_LT(r.seconds, 1.0) << what << ": GET " << target;
    }
    const auto analysis = api.post(run + "/analyses", {{"kind", "compare"}, {"model", "nominal"}});
    EXPECT_LT(analysis.status, 500) << what << ": " << analysis.body;
    EXPECT_FALSE(has(analysis.body, kSecret)) << what;
  }
  // The list reads every run.json; what cannot be read is named, nothing is quoted.
  const Timed list = timed_get(api, "/api/runs");
  EXPECT_EQ(list.status, 200) << list.body;
  EXPECT_FALSE(has(list.body, kSecret));
  EXPECT_LT(list.seconds, 5.0);
  EXPECT_EQ(api.get("/api/health").status, 200);
  std::printf("slowest refusal: %.3f s\n", slowest_s);
  // And the server ends on SIGTERM: no thread is left in an open() of a FIFO.
  const auto t0 = std::chrono::steady_clock::now();
  const auto rc = server.terminate(5s);
  ASSERT_TRUE(rc.has_value()) << "hilbench serve did not exit within 5 s of SIGTERM";
  std::printf("SIGTERM to exit: %.3f s\n", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
}
