// The operator console's server side, against the real `hilbench serve`: GET / (the page, and the
// token form that is all it serves without the token) and GET /api/runs/{id}/report.html. The page
// itself is driven in Chromium by tests/console/.
#include <gtest/gtest.h>

#include <fstream>

#include "hil/bench/rt/rig_config.hpp"
#include "server_process.hpp"

using namespace std::chrono_literals;
using hil::test::ServerProcess;
using nlohmann::json;

namespace {

// The start of Debian's dygraphs build, as installed: the page must carry the library itself.
std::string dygraphs_head() {
  std::ifstream in("/usr/share/javascript/dygraphs/dygraph.min.js");
  std::string head(200, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  return head;
}

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

}  // namespace

TEST(ConsoleApi, OffLoopbackThePageNeedsTheTokenAndWithoutItOnlyAFormIsServed) {
  ServerProcess server({"--listen", "0.0.0.0:0"}, "s3cret-token");
  const auto anonymous = server.client("");
  const auto wrong = server.client("guess-guess");
  const auto right = server.client("s3cret-token");

  for (const auto& [who, target] : {std::pair{&anonymous, "/"}, {&wrong, "/"}, {&anonymous, "/?token=guess-guess"}}) {
    const auto r = who->get(target);
    EXPECT_EQ(r.status, 401) << target;
    EXPECT_TRUE(has(r.content_type, "text/html")) << r.content_type;
    EXPECT_TRUE(has(r.body, "<form method=\"get\" action=\"/\">")) << r.body;
    EXPECT_TRUE(has(r.body, "name=\"token\"")) << r.body;
    // Nothing of the console: neither its script nor the plotting library nor any endpoint.
    EXPECT_FALSE(has(r.body, "/api/")) << r.body;
    EXPECT_FALSE(has(r.body, "Dygraph")) << r.body;
    EXPECT_LT(r.body.size(), 2000u);
  }
  EXPECT_EQ(anonymous.get("/api/runs/x/report.html").status, 401);
  EXPECT_EQ(anonymous.get("/api/runs/x/report.html").json()["error"], "unauthorized");

  const std::string head = dygraphs_head();
  ASSERT_GT(head.size(), 100u) << "libjs-dygraphs is not installed";
  for (const auto& [who, target] : {std::pair{&right, "/"}, {&anonymous, "/?token=s3cret-token"}}) {
    const auto r = who->get(target);
    ASSERT_EQ(r.status, 200) << target;
    EXPECT_TRUE(has(r.content_type, "text/html")) << r.content_type;
    EXPECT_TRUE(has(r.body, "live view decimated; telemetry.csv is the lossless record"));
    EXPECT_TRUE(has(r.body, head)) << "the page does not carry Debian's dygraph.min.js";
    EXPECT_TRUE(has(r.body, "/api/telemetry?rate_hz=30"));
    // Offline: nothing is loaded from elsewhere.
    EXPECT_FALSE(has(r.body, "<script src")) << target;
    EXPECT_FALSE(has(r.body, "<link rel=\"stylesheet\"")) << target;
  }
}

TEST(ConsoleApi, ARunsReportIsMadeOnceItEndsAndItsFaultsAreNamed) {
  ServerProcess server;
  const auto api = server.client();
  const json routes = api.get("/api").json()["endpoints"];
  auto listed = [&](const std::string& path) {
    return std::any_of(routes.begin(), routes.end(), [&](const json& r) { return r["path"] == path && r["method"] == "GET"; });
  };
  EXPECT_TRUE(listed("/"));
  EXPECT_TRUE(listed("/api/runs/{id}/report.html"));

  EXPECT_EQ(api.get("/api/runs/nope/report.html").status, 404);
  EXPECT_EQ(api.get("/api/runs/..%2F..%2Fetc/report.html").status, 404);

  const std::string yaml = hil::test::short_campaign_yaml(30, "review");
  ASSERT_EQ(
      api.request("POST", "/api/start", json{{"campaign_yaml", yaml}, {"runs", {"adaptive"}}}.dump(), "application/json").status,
      202);
  json s = hil::test::wait_status(
      api, [](const json& x) { return hil::test::status_t(x) >= 1.0; }, 30s);
  const std::string id = s["run_dir"];
  // Loop health the console shows: the telemetry ring the sim rig's file asks for (a power of two).
  const auto ring_rows = hil::bench::load_rig_config(hil::test::source_path("configs/rigs/sim.yaml")).loop.ring_rows;
  std::size_t capacity = 1;
  while (capacity < static_cast<std::size_t>(ring_rows)) capacity *= 2;
  EXPECT_EQ(s["telemetry"]["ring_capacity"], capacity) << s.dump(2);
  EXPECT_LE(s["telemetry"]["ring_fill"].get<std::size_t>(), capacity) << s.dump(2);
  const auto running = api.get("/api/runs/" + id + "/report.html");
  EXPECT_EQ(running.status, 409) << running.body;
  EXPECT_EQ(running.json()["error"], "the run is still running");
  EXPECT_FALSE(std::filesystem::exists(server.runs_dir() / id / "report.html"));

  ASSERT_EQ(api.post("/api/abort", json::object()).status, 202);
  s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 30s);
  ASSERT_EQ(s["last"]["outcome"], "aborted") << s.dump(2);

  const auto report = api.get("/api/runs/" + id + "/report.html");
  ASSERT_EQ(report.status, 200) << report.body;
  EXPECT_TRUE(has(report.content_type, "text/html")) << report.content_type;
  EXPECT_TRUE(has(report.body, "<figure class=\"hil-fig")) << report.body.substr(0, 500);
  EXPECT_TRUE(has(report.body, "adaptive aborted (operator abort")) << "the report names how the run ended";
  // Kept in the run's folder, and served from there the next time without being made again.
  const auto kept = server.runs_dir() / id / "report.html";
  ASSERT_TRUE(std::filesystem::exists(kept));
  EXPECT_EQ(hil::test::slurp(kept), report.body);
  const auto made = std::filesystem::last_write_time(kept);
  std::this_thread::sleep_for(20ms);
  EXPECT_EQ(api.get("/api/runs/" + id + "/report.html").body, report.body);
  EXPECT_EQ(std::filesystem::last_write_time(kept), made);

  // A run whose telemetry is damaged: the reply names the file, and no half report is left.
  const auto broken = server.runs_dir() / "broken_run";
  std::filesystem::create_directory(broken);
  std::filesystem::copy_file(server.runs_dir() / id / "run.json", broken / "run.json");
  std::ofstream(broken / "telemetry.csv") << "t_s,theta_cmd_deg\n0.000,abc\n";
  const auto refused = api.get("/api/runs/broken_run/report.html");
  EXPECT_EQ(refused.status, 422) << refused.body;
  EXPECT_EQ(refused.json()["error"], "cannot make the report");
  EXPECT_TRUE(has(refused.json().value("detail", ""), "telemetry.csv")) << refused.body;
  EXPECT_FALSE(std::filesystem::exists(broken / "report.html"));
  EXPECT_FALSE(std::filesystem::exists(broken / "report.html.tmp"));
  EXPECT_EQ(api.get("/api/health").status, 200);
}
