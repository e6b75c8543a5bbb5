// End to end: the real `hilbench serve` process on an ephemeral port, driven only through its
// HTTP/WebSocket API (and, once, through `hilbench ctl`).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <set>
#include <thread>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/run_report.hpp"
#include "hil/bench/campaign/sim.hpp"
#include "hil/bench/rt/run_record.hpp"
#include "hil/csv_reader.hpp"
#include "loop_fixture.hpp"
#include "server_process.hpp"

using namespace std::chrono_literals;
using hil::test::ServerProcess;
using nlohmann::json;

namespace {

constexpr std::uint32_t kSafeStateFlag = 1u << 6;  // LoopFlag kFlagSafeState

// Every row of a run's telemetry, strictly parsed (a bad cell or a time going back throws).
hil::CsvChunk read_telemetry(const std::filesystem::path& run_dir) {
  return hil::read_csv(run_dir / "telemetry.csv", {{"t_s", "theta_cmd_deg", "p_meas_mpa", "gap_true_deg", "loop_flags",
                                                    "wake_latency_us", "compute_us", "comp_deg"},
                                                   {},
                                                   "t_s"});
}

const json* find_event(const std::vector<json>& events, const std::string& kind) {
  for (const auto& e : events) {
    if (e.value("kind", "") == kind) return &e;
  }
  return nullptr;
}

}  // namespace

// The acceptance run: paper_adaptive's adaptive run in real time (18 s at 1 kHz). The campaign's
// "none" run is left out only to keep the suite short: it adds 18 s and nothing new to check.
TEST(ServerEndToEnd, PaperAdaptiveWithGapInjectionAndLiveTelemetry) {
  ServerProcess server;
  const auto api = server.client();
  ASSERT_EQ(api.get("/api/health").status, 200);

  // Live telemetry at 50 Hz, collected until the campaign ends.
  std::mutex mutex;
  std::vector<json> rows;
  std::vector<json> notices;
  std::atomic<bool> ws_open{false};
  std::thread ws([&] {
    server.client().stream("/api/telemetry?rate_hz=50", [&](const std::string& m) {
      const json j = json::parse(m);
      std::lock_guard lock(mutex);
      if (j["type"] == "hello") ws_open = true;
      if (j["type"] == "row") rows.push_back(j);
      if (j["type"] != "row" && j["type"] != "hello") notices.push_back(j);
      return j["type"] != "campaign_end";
    });
  });
  for (int i = 0; i < 500 && !ws_open; ++i) std::this_thread::sleep_for(10ms);
  ASSERT_TRUE(ws_open);

  const auto started = api.post("/api/start", {{"campaign", "paper_adaptive"}, {"runs", {"adaptive"}}});
  ASSERT_EQ(started.status, 202) << started.body;

  // Watch telemetry arrive, then change the gap at ~3 s.
  json s = hil::test::wait_status(
      api, [](const json& x) { return hil::test::status_t(x) >= 3.0; }, 30s);
  ASSERT_GE(hil::test::status_t(s), 3.0) << s.dump(2);
  {
    std::lock_guard lock(mutex);
    EXPECT_GT(rows.size(), 50u);  // ~150 expected by now
  }
  const auto injected = api.post("/api/inject/gap", {{"gap_deg", 2.5}});
  ASSERT_EQ(injected.status, 202) << injected.body;

  // Status while running: state, campaign, progress, loop statistics, the active fault.
  s = hil::test::wait_status(
      api, [](const json& x) { return !x.value("faults", json::array()).empty(); }, 5s);
  EXPECT_EQ(s["state"], "running");
  EXPECT_EQ(s["campaign"], "paper_adaptive");
  EXPECT_EQ(s["run"], "adaptive");
  EXPECT_GT(s["progress"]["fraction"].get<double>(), 0.1);
  EXPECT_GT(s["loop"]["periods"].get<long>(), 3000);
  EXPECT_TRUE(s["loop"]["wake_latency_us"].contains("p99_us"));
  EXPECT_TRUE(s["loop"]["compute_us"].contains("p99_9_us"));
  ASSERT_EQ(s["faults"].size(), 1u) << s.dump(2);
  EXPECT_EQ(s["faults"][0]["kind"], "gap");
  EXPECT_DOUBLE_EQ(s["faults"][0]["gap_deg"].get<double>(), 2.5);
  EXPECT_EQ(s["telemetry"]["rows_lost"], 0);

  // Let it finish.
  s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 40s);
  ASSERT_EQ(s["state"], "idle") << s.dump(2);
  EXPECT_EQ(s["last"]["outcome"], "completed") << s.dump(2);
  ws.join();

  // The files.
  const auto dir = hil::test::only_run(server.runs_dir());
  EXPECT_NE(dir.filename().string().find("_paper_adaptive_adaptive"), std::string::npos);
  const json run = json::parse(hil::test::slurp(dir / "run.json"));
  EXPECT_EQ(run["outcome"], "completed");
  EXPECT_EQ(run["telemetry"]["rows_written"], 18000);
  EXPECT_EQ(run["telemetry"]["rows_lost"], 0);
  EXPECT_EQ(run["telemetry"]["events_lost"], 0);
  EXPECT_EQ(run["loop"]["periods"], 18000);
  EXPECT_TRUE(run["config"]["campaign_yaml"].get<std::string>().find("paper_adaptive") != std::string::npos);
  EXPECT_FALSE(run["host"].get<std::string>().empty());
  EXPECT_FALSE(run["start_utc"].is_null());
  EXPECT_FALSE(run["stop_utc"].is_null());

  const auto events = hil::test::read_jsonl(dir / "events.jsonl");
  const json* gap = find_event(events, "gap_change");
  ASSERT_NE(gap, nullptr);
  EXPECT_DOUBLE_EQ((*gap)["gap_deg"].get<double>(), 2.5);
  const double t_gap = (*gap)["t_s"].get<double>();
  EXPECT_GE(t_gap, 3.0);
  EXPECT_LT(t_gap, 12.0);

  const auto csv = read_telemetry(dir);
  ASSERT_EQ(csv.rows(), 18000u);
  for (std::size_t i = 0; i < csv.rows(); ++i) {
    const double t = csv.values[0][i];
    ASSERT_NEAR(t, i * 1e-3, 1e-9);
    const double expected_gap = t >= t_gap - 1e-9 ? 2.5 : 1.0;  // the programme's 2 deg at 12 s is overridden
    ASSERT_DOUBLE_EQ(csv.values[3][i], expected_gap) << "t = " << t;
  }

  // The WebSocket rows: decimated to ~50 Hz, and they saw the change too.
  std::lock_guard lock(mutex);
  EXPECT_GT(rows.size(), 600u);
  EXPECT_LT(rows.size(), 1100u);
  EXPECT_DOUBLE_EQ(rows.back()["gap_true_deg"].get<double>(), 2.5);
  // Every compensation jump (one 1 ms period each, seconds apart) reaches the 50 Hz stream with its
  // size: the next row sent carries the largest jump of the rows skipped before it.
  std::vector<double> jumps_csv, jumps_ws;
  for (std::size_t i = 0; i < csv.rows(); ++i)
    if (csv.values[7][i] != 0) jumps_csv.push_back(csv.values[7][i]);
  for (const auto& row : rows)
    if (row["comp_deg"].is_number() && row["comp_deg"].get<double>() != 0) jumps_ws.push_back(row["comp_deg"].get<double>());
  ASSERT_GE(jumps_csv.size(), 5u);
  ASSERT_EQ(jumps_ws.size(), jumps_csv.size());
  for (std::size_t k = 0; k < jumps_csv.size(); ++k) EXPECT_NEAR(jumps_ws[k], jumps_csv[k], 1e-5) << "jump " << k;
  EXPECT_NE(std::find_if(notices.begin(), notices.end(), [](const json& n) { return n["type"] == "run_start"; }), notices.end());

  // Past runs are listed and their files download.
  const json list = api.get("/api/runs").json();
  ASSERT_EQ(list["runs"].size(), 1u);
  EXPECT_EQ(list["runs"][0]["id"], dir.filename().string());
  EXPECT_EQ(list["runs"][0]["outcome"], "completed");
  const auto copy = server.dir() / "download.csv";
  const auto got = api.download("/api/runs/" + dir.filename().string() + "/telemetry.csv", copy);
  EXPECT_EQ(got.status, 200);
  EXPECT_EQ(hil::test::slurp(copy), hil::test::slurp(dir / "telemetry.csv"));
}

TEST(ServerEndToEnd, SigtermMidRunAbortsSafelyAndKeepsEveryRow) {
  ServerProcess server;
  const auto api = server.client();
  ASSERT_EQ(api.post("/api/start", {{"campaign_yaml", hil::test::short_campaign_yaml(10)}}).status, 202);
  const json s = hil::test::wait_status(
      api, [](const json& x) { return hil::test::status_t(x) >= 1.5; }, 20s);
  const double t_before = hil::test::status_t(s);
  ASSERT_GE(t_before, 1.5);
  const auto rc = server.terminate(10s);
  ASSERT_TRUE(rc.has_value()) << "hilbench serve did not exit after SIGTERM";
  EXPECT_EQ(*rc, 0);

  const auto dir = hil::test::only_run(server.runs_dir());
  const json run = json::parse(hil::test::slurp(dir / "run.json"));
  EXPECT_EQ(run["outcome"], "aborted");
  EXPECT_NE(run["reason"].get<std::string>().find("SIGTERM"), std::string::npos) << run["reason"];
  EXPECT_EQ(run["trip"]["reason"], "operator abort");
  EXPECT_EQ(run["telemetry"]["rows_lost"], 0);

  // Every row parses, none is missing, and the rows reach past the moment of the signal.
  const auto csv = read_telemetry(dir);
  ASSERT_EQ(csv.rows(), run["telemetry"]["rows_written"].get<std::size_t>());
  ASSERT_EQ(csv.rows(), run["periods_run"].get<std::size_t>());
  for (std::size_t i = 0; i < csv.rows(); ++i) ASSERT_NEAR(csv.values[0][i], i * 1e-3, 1e-9);
  EXPECT_GE(csv.values[0].back(), t_before);
  EXPECT_LT(csv.values[0].back(), 9.0);  // it did not run to the end
  // The safe state (hold) is in the last rows.
  EXPECT_TRUE(static_cast<std::uint32_t>(csv.values[4].back()) & kSafeStateFlag);

  const auto events = hil::test::read_jsonl(dir / "events.jsonl");
  const json* request = find_event(events, "abort_request");
  ASSERT_NE(request, nullptr);
  EXPECT_NE((*request)["reason"].get<std::string>().find("SIGTERM"), std::string::npos);
  ASSERT_NE(find_event(events, "trip"), nullptr);
  EXPECT_EQ((*find_event(events, "trip"))["reason"], "operator abort");
  EXPECT_NE(find_event(events, "safe_state"), nullptr);
}

TEST(ServerEndToEnd, WatchdogReachesTheSafeStateWithinThreePeriods) {
  ServerProcess server;
  const auto api = server.client();
  ASSERT_EQ(api.post("/api/start", {{"campaign_yaml", hil::test::short_campaign_yaml(6)}}).status, 202);
  hil::test::wait_status(
      api, [](const json& x) { return hil::test::status_t(x) >= 1.0; }, 20s);
  const auto r = api.post("/api/inject/rig", {{"mode", "silent"}});
  ASSERT_EQ(r.status, 202) << r.body;
  const json s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 20s);
  ASSERT_EQ(s["state"], "idle");
  EXPECT_EQ(s["last"]["outcome"], "aborted");

  const auto dir = hil::test::only_run(server.runs_dir());
  const json run = json::parse(hil::test::slurp(dir / "run.json"));
  EXPECT_EQ(run["outcome"], "aborted");
  EXPECT_EQ(run["trip"]["reason"], "watchdog");
  EXPECT_NE(run["reason"].get<std::string>().find("watchdog: 3 rig reads missed in a row"), std::string::npos) << run["reason"];

  const auto events = hil::test::read_jsonl(dir / "events.jsonl");
  const json* silent = find_event(events, "rig_fault");
  const json* trip = find_event(events, "trip");
  const json* safe = find_event(events, "safe_state");
  ASSERT_TRUE(silent && trip && safe);
  EXPECT_EQ((*trip)["reason"], "watchdog");
  const long p_silent = (*silent)["period"], p_trip = (*trip)["period"], p_safe = (*safe)["period"];
  EXPECT_LE(p_safe - p_silent, 3) << "safe state " << p_safe - p_silent << " periods after the rig fell silent";
  EXPECT_EQ(p_safe, p_trip);

  const auto csv = read_telemetry(dir);
  ASSERT_GT(csv.rows(), static_cast<std::size_t>(p_safe));
  const double held = csv.values[1][static_cast<std::size_t>(p_safe)];
  for (std::size_t i = static_cast<std::size_t>(p_safe); i < csv.rows(); ++i) {
    ASSERT_TRUE(static_cast<std::uint32_t>(csv.values[4][i]) & kSafeStateFlag) << "row " << i;
    ASSERT_EQ(csv.values[1][i], held) << "row " << i;  // safe_state: hold
  }
}

TEST(ServerEndToEnd, BadRequestsGetClearErrorsAndTheServerKeepsServing) {
  ServerProcess server;
  const auto api = server.client();
  auto expect_error = [&](const hil::bench::ApiReply& r, int status, const std::string& detail_part) {
    EXPECT_EQ(r.status, status) << r.body;
    const json j = r.json();
    EXPECT_TRUE(j.contains("error")) << r.body;
    if (!detail_part.empty()) {
      EXPECT_NE(j.value("detail", "").find(detail_part), std::string::npos) << r.body;
    }
  };
  expect_error(api.request("POST", "/api/start", "{\"campaign\": ", "application/json"), 400, "parse error");
  expect_error(api.post("/api/start", {{"campaign", "paper_adaptiv"}}), 404, "did you mean 'paper_adaptive'");
  expect_error(api.post("/api/start", {{"campaign", "../../etc/passwd"}}), 404, "");
  expect_error(api.post("/api/start", {{"campaign_yaml", "name: x\nduration_s: [1\n"}}), 400, "posted campaign");
  expect_error(api.post("/api/start", {{"campaign_yaml", hil::test::short_campaign_yaml(2) + "bogus_key: 1\n"}}), 400,
               "bogus_key");
  expect_error(api.request("POST", "/api/start", "name: x\n", "application/yaml"), 400, "posted campaign");
  // A raw YAML body takes its options in the query; a misspelt one is refused, not ignored.
  expect_error(api.request("POST", "/api/start?run=adaptive", hil::test::short_campaign_yaml(2), "application/yaml"), 400,
               "'run' (did you mean 'runs'?)");
  // A period too short for its duration would hold the request thread for hours while it loads.
  {
    std::string yaml = hil::test::short_campaign_yaml(604800);
    yaml.replace(yaml.find("period_ms: 1\n"), 13, "period_ms: 0.01\n");
    expect_error(api.post("/api/start", {{"campaign_yaml", yaml}}), 400, "periods; at most 604800000 (7 days at 1 kHz)");
    yaml.replace(yaml.find("period_ms: 0.01\n"), 16, "period_ms: 0.000001\n");
    expect_error(api.post("/api/start", {{"campaign_yaml", yaml}}), 400, "must be 0.01..1000 ms");
  }
  expect_error(api.post("/api/start", {{"campaign", "paper_adaptive"}, {"rigg", "sim"}}), 400, "did you mean 'rig'");
  expect_error(api.post("/api/start", {{"campaign", "paper_adaptive"}, {"rig", "can0"}}), 404, "not a rig");
  expect_error(api.post("/api/start", {{"campaign", "paper_adaptive"}, {"runs", {"adaptiv"}}}), 400, "did you mean 'adaptive'");
  expect_error(
      api.request("POST", "/api/start", "{\"campaign_yaml\": \"" + std::string(2 << 20, 'x') + "\"}", "application/json"), 413,
      "limit");
  expect_error(api.post("/api/inject/gap", {{"gap_deg", 2}}), 409, "no campaign is running");
  expect_error(api.post("/api/stop", json::object()), 409, "");
  expect_error(api.post("/api/abort", json::object()), 409, "");
  expect_error(api.get("/api/nothing"), 404, "GET /api/runs/{id}/{file}");  // the list of endpoints
  expect_error(api.get("/nothing"), 404, "the API lives under /api");
  expect_error(api.get("/api/start"), 405, "POST");
  expect_error(api.post("/api/runs", json::object()), 405, "GET");
  {  // GET /api: every endpoint, with what it does
    const auto index = api.get("/api");
    ASSERT_EQ(index.status, 200) << index.body;
    std::set<std::string> endpoints;
    const json listed = index.json();  // kept: a range-for over a temporary's member would dangle
    for (const auto& e : listed["endpoints"]) {
      EXPECT_FALSE(e["summary"].get<std::string>().empty());
      endpoints.insert(e["method"].get<std::string>() + " " + e["path"].get<std::string>());
    }
    for (const char* e : {"GET /api/health", "GET /api/status", "POST /api/start", "POST /api/stop", "POST /api/abort",
                          "POST /api/inject/{kind}", "GET /api/runs", "GET /api/runs/{id}", "GET /api/runs/{id}/{file}",
                          "GET /api/telemetry", "GET /api/campaigns", "GET /api/rigs"}) {
      EXPECT_EQ(endpoints.count(e), 1u) << e;
    }
  }
  expect_error(api.get("/api/runs/..%2F..%2Fetc/passwd"), 404, "");
  expect_error(api.get("/api/runs/nope"), 404, "");

  // Still serving: a real start, then a second one is refused while it runs.
  const auto started = api.post("/api/start", {{"campaign_yaml", hil::test::short_campaign_yaml(30)}});
  ASSERT_EQ(started.status, 202) << started.body;
  expect_error(api.post("/api/start", {{"campaign", "paper_adaptive"}}), 409, "is running");
  hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "running"; }, 10s);
  expect_error(api.post("/api/inject/sensor", {{"mode", "wobble"}}), 400, "stuck, dropout, bias or noise");
  expect_error(api.post("/api/inject/gap", {{"gap_deg", -1}}), 400, "0..10");
  expect_error(api.post("/api/inject/gap", {{"gap_deg", "two"}}), 400, "number");
  expect_error(api.post("/api/inject/sensor", {{"mode", "bias"}}), 400, "bias_kpa");
  expect_error(api.post("/api/inject/sensor", {{"mode", "noise"}, {"rms_kpa", 5}, {"duration_s", -2}}), 400, "duration_s");
  expect_error(api.post("/api/inject/wobble", json::object()), 404, "gap, sensor, drive, rig or clear");
  // A bias or noise of 1e308 kPa was accepted (202) and telemetry.csv held 'nan': refused now,
  // naming the field (issue 38 item 4).
  for (const auto& [body, field] : {std::pair{json{{"mode", "bias"}, {"bias_kpa", 1e308}}, "bias_kpa"},
                                    std::pair{json{{"mode", "noise"}, {"rms_kpa", 1e308}}, "rms_kpa"},
                                    std::pair{json{{"mode", "bias"}, {"bias_kpa", -10001}}, "bias_kpa"}}) {
    const auto reply = api.post("/api/inject/sensor", body);
    expect_error(reply, 400, "is outside");
    EXPECT_EQ(reply.json().value("field", ""), field) << reply.body;
  }
  EXPECT_EQ(api.post("/api/inject/sensor", {{"mode", "noise"}, {"rms_kpa", 1}, {"duration_s", 0.1}}).status, 202);
  EXPECT_EQ(api.post("/api/inject/drive", {{"duration_s", 0.05}}).status, 202);
  EXPECT_EQ(api.post("/api/inject/clear", json::object()).status, 202);
  EXPECT_EQ(api.get("/api/health").status, 200);
  const auto aborted = api.post("/api/abort", {{"reason", "end of test"}});
  EXPECT_EQ(aborted.status, 202) << aborted.body;
  const json s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 10s);
  EXPECT_EQ(s["last"]["outcome"], "aborted");
  EXPECT_EQ(s["last"]["reason"], "operator abort: end of test");
  const auto events = hil::test::read_jsonl(hil::test::only_run(server.runs_dir()) / "events.jsonl");
  for (const char* kind : {"sensor_fault", "drive_fault", "faults_cleared", "abort_request", "trip", "safe_state"}) {
    EXPECT_NE(find_event(events, kind), nullptr) << kind;
  }
}

TEST(ServerEndToEnd, TokenRequiredOffLoopback) {
  // Without a token the server refuses to listen beyond loopback.
  hil::test::TempDir dir;
  const pid_t pid = hil::test::spawn({hil::test::hilbench_exe(), "serve", "--listen", "0.0.0.0:0", "--configs",
                                      hil::test::source_path("configs").string(), "--runs-dir", (dir.path() / "runs").string()},
                                     dir.path() / "log");
  const auto rc = hil::test::wait_exit(pid, 10s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 1);
  EXPECT_NE(hil::test::slurp(dir.path() / "log").find("requires a token"), std::string::npos);

  // With one, every request must carry it (reached here through 127.0.0.1).
  ServerProcess server({"--listen", "0.0.0.0:0"}, "s3cret-token");
  const auto anonymous = server.client("");
  const auto wrong = server.client("guess");
  const auto right = server.client("s3cret-token");
  for (const auto* target : {"/api/status", "/api/campaigns", "/api/runs"}) {
    EXPECT_EQ(anonymous.get(target).status, 401) << target;
    EXPECT_EQ(wrong.get(target).status, 401) << target;
    EXPECT_EQ(right.get(target).status, 200) << target;
  }
  const auto refused = anonymous.post("/api/start", {{"campaign", "paper_adaptive"}});
  EXPECT_EQ(refused.status, 401);
  EXPECT_EQ(refused.json()["error"], "unauthorized");
  try {
    anonymous.stream("/api/telemetry", [](const std::string&) { return false; });
    ADD_FAILURE() << "the stream was opened without the token";
  } catch (const hil::bench::ApiRefused& e) {  // the server's reply, and its reason in what()
    EXPECT_EQ(e.reply().status, 401);
    EXPECT_EQ(e.reply().json()["error"], "unauthorized");
    EXPECT_NE(std::string(e.what()).find("HTTP 401 instead of the upgrade: {"), std::string::npos) << e.what();
  }
  EXPECT_EQ(right.get("/api/status").json()["state"], "idle");  // nothing started
}

TEST(ServerEndToEnd, CtlStartsAndFollowsWithAProgressBar) {
  ServerProcess server;
  const auto yaml = server.dir() / "two_seconds.yaml";
  std::ofstream(yaml) << hil::test::short_campaign_yaml(2, "two_seconds");
  const std::string url = "http://127.0.0.1:" + std::to_string(server.port());
  const auto log = server.dir() / "ctl.log";
  const pid_t pid =
      hil::test::spawn({hil::test::hilbench_exe(), "ctl", "--server", url, "start", yaml.string(), "--speed", "2"}, log);
  const auto rc = hil::test::wait_exit(pid, 30s);
  ASSERT_TRUE(rc.has_value());
  const std::string out = hil::test::slurp(log);
  EXPECT_EQ(*rc, 0) << out;
  EXPECT_NE(out.find("started two_seconds on sim"), std::string::npos) << out;
  // Not a terminal: hil::ProgressLine's log policy, a line a tenth of the campaign.
  EXPECT_NE(out.find("two_seconds:   0% none (1/2), t "), std::string::npos) << out;
  EXPECT_NE(out.find("% none (1/2), t 1"), std::string::npos) << out;
  EXPECT_NE(out.find("% adaptive (2/2), t "), std::string::npos) << out;
  EXPECT_NE(out.find(", rows not recorded 0"), std::string::npos) << out;
  EXPECT_NE(out.find("last campaign: two_seconds on sim: completed"), std::string::npos) << out;

  const pid_t status = hil::test::spawn({hil::test::hilbench_exe(), "ctl", "--server", url, "runs"}, server.dir() / "runs.log");
  ASSERT_EQ(hil::test::wait_exit(status, 10s), 0);
  const std::string runs = hil::test::slurp(server.dir() / "runs.log");
  EXPECT_NE(runs.find("_two_seconds_none"), std::string::npos) << runs;
  EXPECT_NE(runs.find("_two_seconds_adaptive"), std::string::npos) << runs;
}

// The status's progress only goes forward: between two runs, and while a run's record is being
// written after its loop ended, it stays where the run ended (it once fell back to the run's
// start there, and `ctl`'s bar read 0 % at the end). Status polled as fast as it answers.
TEST(ServerEndToEnd, ProgressNeverGoesBack) {
  ServerProcess server;
  const auto api = server.client();
  ASSERT_EQ(api.post("/api/start", {{"campaign_yaml", hil::test::short_campaign_yaml(2, "forward")}, {"speed", 4}}).status, 202);
  double last = 0;
  int polls = 0, between = 0;
  for (const auto end = std::chrono::steady_clock::now() + 60s; std::chrono::steady_clock::now() < end; ++polls) {
    const json s = api.get("/api/status").json();
    if (s["state"] == "idle") break;
    if (s["state"] == "starting") ++between;
    const double f = s["progress"]["fraction"].get<double>();
    ASSERT_GE(f, last) << "poll " << polls << ": " << s.dump(2);
    last = f;
  }
  EXPECT_GT(last, 0.9) << polls << " polls";
  EXPECT_GT(polls, 50);
  std::printf("%d polls, %d between runs\n", polls, between);
}

// A run recorded by the server is reviewed as a simulation is: `hilbench report` gives the same
// metrics as `hilbench sim` for the same campaign (both run the loop's period on the simulated
// rig; only the CSV's rounding differs) and writes the same report.
TEST(ServerEndToEnd, ReportOfRecordedRunsMatchesTheSimulation) {
  ServerProcess server;
  const auto api = server.client();
  const std::string yaml = hil::test::short_campaign_yaml(6, "review");
  ASSERT_EQ(api.request("POST", "/api/start", json{{"campaign_yaml", yaml}, {"speed", 10}}.dump(), "application/json").status,
            202);
  const json s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 60s);
  ASSERT_EQ(s["last"]["outcome"], "completed") << s.dump(2);
  std::vector<std::filesystem::path> dirs;
  for (const auto& e : std::filesystem::directory_iterator(server.runs_dir()))
    if (e.is_directory()) dirs.push_back(e.path());  // the server's .server.lock beside them
  std::sort(dirs.begin(), dirs.end());
  ASSERT_EQ(dirs.size(), 2u);

  const auto log = server.dir() / "report.log";
  const pid_t pid = hil::test::spawn(
      {hil::test::hilbench_exe(), "report", dirs[0].string(), dirs[1].string(), "--out", (server.dir() / "review.html").string()},
      log);
  ASSERT_EQ(hil::test::wait_exit(pid, 60s), 0) << hil::test::slurp(log);
  EXPECT_NE(hil::test::slurp(log).find("completed"), std::string::npos) << hil::test::slurp(log);
  EXPECT_GT(std::filesystem::file_size(server.dir() / "review.html"), 10000u);

  const auto runs = hil::bench::write_run_report(dirs, server.dir() / "again.html");
  const auto campaign = hil::bench::load_campaign_text(yaml, "review.yaml", hil::test::source_path("configs/campaigns"));
  ASSERT_EQ(runs.size(), 2u);
  for (const auto& r : runs) {
    const auto sim = hil::bench::summarise_run(campaign, hil::test::run_named(campaign, r.digest.name));
    const auto& got = r.digest.summary;
    EXPECT_NEAR(got.iae_mpa_s, sim.iae_mpa_s, 1e-3 * sim.iae_mpa_s) << r.digest.name;
    ASSERT_EQ(got.reversals.size(), sim.reversals.size()) << r.digest.name;
    for (std::size_t i = 0; i < sim.reversals.size(); ++i) {
      EXPECT_NEAR(got.reversals[i].stall_s, sim.reversals[i].stall_s, 0.005) << r.digest.name << " reversal " << i;
      EXPECT_NEAR(got.reversals[i].gap_est_deg, sim.reversals[i].gap_est_deg, 1e-4) << r.digest.name << " reversal " << i;
    }
    EXPECT_EQ(got.touch_state_changes, sim.touch_state_changes) << r.digest.name;
  }

  // run.json keeps the plant the run had (its absolute path and text): the report is still made,
  // the same, when the bench's configs have moved away (a review on another machine).
  const std::string nominal = hil::test::slurp(hil::test::source_path("configs/plant/nominal.yaml"));
  for (const auto& dir : dirs) {
    hil::bench::RunRecord record = hil::bench::read_run_record(dir);
    EXPECT_EQ(record.config.plant_yaml, nominal);
    EXPECT_TRUE(std::filesystem::path(record.config.plant_file).is_absolute()) << record.config.plant_file;
    EXPECT_TRUE(std::filesystem::path(record.config.campaign_file).is_absolute()) << record.config.campaign_file;
    record.config.campaign_file = "/nonexistent/configs/campaigns/review.yaml";
    record.config.plant_file = "/nonexistent/configs/plant/nominal.yaml";
    hil::bench::write_run_record(dir, record);
  }
  const auto moved = hil::bench::write_run_report(dirs, server.dir() / "moved.html");
  ASSERT_EQ(moved.size(), runs.size());
  for (std::size_t i = 0; i < runs.size(); ++i) {
    EXPECT_EQ(moved[i].digest.summary.iae_mpa_s, runs[i].digest.summary.iae_mpa_s) << runs[i].digest.name;
    EXPECT_EQ(moved[i].digest.summary.touch_state_changes, runs[i].digest.summary.touch_state_changes);
  }
}
