// Analyses of recorded runs against the real `hilbench serve` (POST/GET /api/runs/{id}/analyses,
// GET /api/models) and the job worker they and the run reports share: compare and diagnose of a
// run with a gap step (1 -> 2 deg at 4 s; the nominal model has 1 deg), judged against the
// campaign's own gap programme and against `hilbench compare` run on the same file; hostile
// requests; the io thread answering while a job runs (by the job's state, not by timing); the
// bounded queue; the report waiting on the worker; shutdown stopping a running diagnosis, and its
// failure still listed by the next server; `hilbench ctl analyse`, `analyses` and `get` of an
// analysis's file.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>

#include "run_folder.hpp"
#include "server_process.hpp"
#include "small_disk.hpp"

using namespace std::chrono_literals;
using hil::test::ServerProcess;
using nlohmann::json;

namespace {

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

std::size_t count(const std::string& text, const std::string& part) {
  std::size_t n = 0;
  for (auto at = text.find(part); at != std::string::npos; at = text.find(part, at + part.size())) ++n;
  return n;
}

// An 8 s campaign on the nominal plant whose true gap steps from 1 to 2 deg at 4 s: what the
// nominal model (1 deg, no change) lacks is that step.
const std::string kGapStepYaml = R"(name: gap_step
description: the gap steps from 1 to 2 deg at 4 s
plant: ../plant/nominal.yaml
duration_s: 8
period_ms: 1
seed: 1
sensor_noise_kpa: 2.0
reference:
  initial_mpa: 1.0
  profile:
    - square: {from_s: 0.5, half_period_s: 1.0, low_mpa: 1.0, high_mpa: 1.5}
gap:
  initial_deg: 1.0
  changes:
    - step: {at_s: 4, to_deg: 2.0}
runs:
  - name: adaptive
    compensation: adaptive
)";

// Records kGapStepYaml's run (at 4 periods per period of wall time: 2 s) and returns its id.
std::string record_run(const hil::bench::ApiClient& api) {
  const auto started = api.post("/api/start", {{"campaign_yaml", kGapStepYaml}, {"speed", 4}});
  if (started.status != 202) throw std::runtime_error("start: " + started.body);
  const json s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle" && x["last"].is_object(); }, 120s);
  if (!s["last"].is_object() || s["last"]["outcome"] != "completed")
    throw std::runtime_error("the run did not complete: " + s.dump());
  return api.get("/api/runs").json()["runs"][0]["id"];
}

json analysis_of(const hil::bench::ApiClient& api, const std::string& run, const std::string& id) {
  const json list = api.get("/api/runs/" + run + "/analyses").json();  // kept: the loop below refers into it
  for (const auto& a : list["analyses"]) {
    if (a["id"] == id) return a;
  }
  return nullptr;
}

template <class Pred>
json wait_analysis(const hil::bench::ApiClient& api, const std::string& run, const std::string& id, Pred pred,
                   std::chrono::seconds timeout = 120s) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  json a;
  do {
    a = analysis_of(api, run, id);
    if (pred(a)) return a;
    std::this_thread::sleep_for(10ms);
  } while (std::chrono::steady_clock::now() < end);
  return a;
}

bool finished(const json& a) { return a.is_object() && (a["state"] == "done" || a["state"] == "failed"); }

std::vector<std::string> files_in(const std::filesystem::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : std::filesystem::directory_iterator(dir)) out.push_back(e.path().filename().string());
  std::sort(out.begin(), out.end());
  return out;
}

// `hilbench ctl --server URL ARGS...` as its own process: the exit status and what it printed.
struct CtlResult {
  int rc = -1;
  std::string out;
};
CtlResult ctl(const ServerProcess& server, std::vector<std::string> args) {
  static int n = 0;
  const auto log = server.dir() / ("ctl_" + std::to_string(++n) + ".log");
  std::vector<std::string> argv = {hil::test::hilbench_exe(), "ctl", "--server",
                                   "http://127.0.0.1:" + std::to_string(server.port())};
  argv.insert(argv.end(), args.begin(), args.end());
  const auto rc = hil::test::wait_exit(hil::test::spawn(argv, log), 180s);
  return {rc.value_or(-1000), hil::test::slurp(log)};
}

std::vector<std::string> leftovers(const std::filesystem::path& runs_dir) {
  std::vector<std::string> out;
  for (const auto& e : std::filesystem::recursive_directory_iterator(runs_dir)) {
    if (e.path().extension() == ".tmp") out.push_back(e.path().string());
  }
  return out;
}

}  // namespace

TEST(AnalysesApi, CompareAndDiagnoseARunOnTheWorkerWhileTheIoThreadAnswers) {
  ServerProcess server({"--max-waiting-jobs", "2"});
  const auto api = server.client();
  const json models = api.get("/api/models").json()["models"];
  ASSERT_TRUE(std::any_of(models.begin(), models.end(), [](const json& m) { return m["name"] == "nominal"; })) << models;

  // A run still running is not analysed.
  ASSERT_EQ(api.post("/api/start", {{"campaign_yaml", kGapStepYaml}}).status, 202);
  const json running = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "running" && x.contains("run_dir"); }, 30s);
  const std::string live_run = running["run_dir"];
  const auto busy = api.post("/api/runs/" + live_run + "/analyses", {{"kind", "compare"}, {"model", "nominal"}});
  EXPECT_EQ(busy.status, 409) << busy.body;
  EXPECT_EQ(busy.json()["error"], "the run is still running");
  ASSERT_EQ(api.post("/api/abort", json::object()).status, 202);
  hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle"; }, 30s);

  const std::string run = record_run(api);
  const std::string base = "/api/runs/" + run + "/analyses";

  // Diagnose first: it keeps the worker busy for a while (seconds here).
  const auto posted = api.post(base, {{"kind", "diagnose"}, {"model", "nominal"}});
  ASSERT_EQ(posted.status, 202) << posted.body;
  const std::string diag_id = posted.json()["analysis"]["id"];
  EXPECT_EQ(posted.json()["analysis"]["state"], "queued");
  json d = wait_analysis(api, run, diag_id, [](const json& a) { return a.is_object() && a["state"] != "queued"; });
  ASSERT_EQ(d["state"], "running") << d.dump(2);

  // While it runs: the io thread answers status, and the report request is queued behind it.
  EXPECT_EQ(api.get("/api/status").status, 200);
  const auto report_queued = api.get("/api/runs/" + run + "/report.html?wait=0");
  EXPECT_EQ(report_queued.status, 202) << report_queued.body;
  EXPECT_EQ(report_queued.json()["report"]["state"], "queued") << report_queued.body;
  const auto again = api.post(base, {{"kind", "diagnose"}, {"model", "nominal"}});
  EXPECT_EQ(again.status, 202);
  EXPECT_EQ(again.json()["analysis"]["id"], diag_id) << "the same analysis in flight is not queued twice: " << again.body;
  const auto compare_posted = api.post(base, {{"kind", "compare"}, {"model", "nominal"}});
  ASSERT_EQ(compare_posted.status, 202) << compare_posted.body;
  const std::string cmp_id = compare_posted.json()["analysis"]["id"];
  const auto full = api.post(base, {{"kind", "compare"}, {"model", "constant_volume"}});
  EXPECT_EQ(full.status, 503) << full.body;
  EXPECT_EQ(full.json()["error"], "cannot queue the job");
  // Every answer above came while the diagnosis was still running: the io thread never waited for it.
  EXPECT_EQ(analysis_of(api, run, diag_id)["state"], "running");

  // The report request that waits (what a browser's link does) gets the report once it is made.
  const auto report = api.get("/api/runs/" + run + "/report.html");
  ASSERT_EQ(report.status, 200) << report.body.substr(0, 300);
  EXPECT_TRUE(has(report.content_type, "text/html"));
  EXPECT_GE(count(report.body, "<figure class=\"hil-fig"), 3u);

  d = wait_analysis(api, run, diag_id, finished);
  const json c = wait_analysis(api, run, cmp_id, finished);
  ASSERT_EQ(d["state"], "done") << d.dump(2);
  ASSERT_EQ(c["state"], "done") << c.dump(2);

  // Diagnose finds the campaign's gap step (1 -> 2 deg at 4 s), which the nominal model lacks.
  const json& dr = d["result"];
  EXPECT_EQ(dr["verdict"], "explained") << dr.dump(2);
  ASSERT_GE(dr["candidates"].size(), 3u) << dr.dump(2);
  EXPECT_EQ(dr["candidates"][0]["effect"], "backlash_change") << dr.dump(2);
  ASSERT_EQ(dr["added"].size(), 1u) << dr.dump(2);
  std::map<std::string, double> fitted;
  for (const auto& p : dr["added"][0]["parameters"]) fitted[p["key"]] = p["value"].get<double>();
  EXPECT_NEAR(fitted["gap_deg"], 1.0, 0.02) << dr.dump(2);
  EXPECT_NEAR(fitted["step_deg"], 1.0, 0.02) << dr.dump(2);
  EXPECT_NEAR(fitted["step_time_s"], 4.0, 0.5) << dr.dump(2);
  const auto diag_report = api.get(d["report"].get<std::string>());
  ASSERT_EQ(diag_report.status, 200);
  EXPECT_TRUE(has(diag_report.body, "nominal.yaml")) << "the report names the model";
  EXPECT_TRUE(has(diag_report.body, "backlash_change"));
  EXPECT_EQ(api.get(base + "/" + diag_id + "/fitted_model.yaml").status, 200);

  // Compare: the same numbers as `hilbench compare` on the run's file, run as its own process.
  const auto cmp_report = api.get(c["report"].get<std::string>());
  ASSERT_EQ(cmp_report.status, 200);
  EXPECT_TRUE(has(cmp_report.body, "nominal.yaml")) << "the report names the model";
  EXPECT_GE(count(cmp_report.body, "<figure class=\"hil-fig"), 1u);
  const auto cli_out = server.dir() / "cli_compare";
  const pid_t pid = hil::test::spawn(
      {hil::test::hilbench_exe(), "compare", "--model", hil::test::source_path("configs/plant/nominal.yaml").string(), "--data",
       (server.runs_dir() / run / "telemetry.csv").string(), "--out", cli_out.string(), "--quiet"},
      server.dir() / "cli.log");
  ASSERT_EQ(hil::test::wait_exit(pid, 120s), 0) << hil::test::slurp(server.dir() / "cli.log");
  const json cli = json::parse(hil::test::slurp(cli_out / "compare.json"));
  EXPECT_DOUBLE_EQ(c["result"]["fit_pct"].get<double>(), cli["fit_pct"].get<double>());
  EXPECT_EQ(json::parse(hil::test::slurp(server.runs_dir() / run / "analyses" / cmp_id / "compare.json"))["fit_pct"],
            cli["fit_pct"]);

  // Everything stayed inside the run's folder, whole.
  for (const auto& id : {diag_id, cmp_id}) {
    EXPECT_TRUE(std::filesystem::exists(server.runs_dir() / run / "analyses" / id / "report.html")) << id;
    EXPECT_TRUE(std::filesystem::exists(server.runs_dir() / run / "analyses" / id / "analysis.json")) << id;
  }
  EXPECT_EQ(leftovers(server.runs_dir()), std::vector<std::string>{});

  // A second compare of the same run is a new analysis beside the first.
  const auto second = api.post(base, {{"kind", "compare"}, {"model", "nominal"}});
  ASSERT_EQ(second.status, 202);
  EXPECT_NE(second.json()["analysis"]["id"], cmp_id);
}

TEST(AnalysesApi, HostileRequestsAreRefusedNamingTheField) {
  ServerProcess server({"--max-body-kb", "64"});
  const auto api = server.client();
  const std::string run = record_run(api);
  const std::string base = "/api/runs/" + run + "/analyses";

  struct Case {
    std::string body;
    int status;
    std::string field;
  };
  const std::vector<Case> cases = {
      {R"({"kind": "comparison", "model": "nominal"})", 400, "kind"},
      {R"({"kind": 3, "model": "nominal"})", 400, "kind"},
      {R"({"model": "nominal"})", 400, "kind"},
      {R"({"kind": "compare"})", 400, "model"},
      {R"({"kind": "compare", "model": "nomnal"})", 404, "model"},
      {R"({"kind": "compare", "model": "../plant/nominal"})", 404, "model"},
      {R"({"kind": "compare", "model": "/etc/passwd"})", 404, "model"},
      {R"({"kind": "compare", "model": "nominal", "out": "/tmp/x"})", 400, "out"},
      {R"([1, 2])", 400, ""},
      {R"({"kind": "compare", "model": )", 400, ""},
  };
  for (const auto& k : cases) {
    const auto r = api.request("POST", base, k.body, "application/json");
    EXPECT_EQ(r.status, k.status) << k.body << " -> " << r.body;
    const json j = r.json();
    EXPECT_TRUE(j.contains("error")) << r.body;
    if (!k.field.empty()) {
      EXPECT_EQ(j.value("field", ""), k.field) << k.body << " -> " << r.body;
      EXPECT_TRUE(has(j.value("detail", ""), "'" + k.field + "'")) << r.body;
    }
  }
  const auto huge = api.request("POST", base, std::string(200 * 1024, ' '), "application/json");
  EXPECT_EQ(huge.status, 413);
  EXPECT_EQ(api.post("/api/runs/nope/analyses", {{"kind", "compare"}, {"model", "nominal"}}).status, 404);
  EXPECT_EQ(api.post("/api/runs/..%2F..%2Fetc/analyses", {{"kind", "compare"}, {"model", "nominal"}}).status, 404);
  EXPECT_EQ(api.get("/api/runs/" + run + "/analyses/nope").status, 404);
  EXPECT_EQ(api.get("/api/runs/" + run + "/analyses/..%2F..%2F" + run + "/run.json").status, 404);

  // A run whose files are bad: no telemetry at all is refused at once; a telemetry.csv the
  // measurement reader refuses fails the job, which names the file; nothing is left behind.
  for (const char* name : {"no_telemetry", "bad_telemetry"}) {
    std::filesystem::create_directory(server.runs_dir() / name);
    std::filesystem::copy_file(server.runs_dir() / run / "run.json", server.runs_dir() / name / "run.json");
  }
  const auto none = api.post("/api/runs/no_telemetry/analyses", {{"kind", "compare"}, {"model", "nominal"}});
  EXPECT_EQ(none.status, 422) << none.body;
  std::ofstream(server.runs_dir() / "bad_telemetry" / "telemetry.csv") << "t_s,theta_cmd_deg,p_meas_mpa\n0.000,1.0,abc\n";
  const auto bad = api.post("/api/runs/bad_telemetry/analyses", {{"kind", "diagnose"}, {"model", "nominal"}});
  ASSERT_EQ(bad.status, 202) << bad.body;
  const std::string id = bad.json()["analysis"]["id"];
  const json failed = wait_analysis(api, "bad_telemetry", id, finished);
  EXPECT_EQ(failed["state"], "failed") << failed.dump(2);
  EXPECT_TRUE(has(failed.value("error", ""), "telemetry.csv:2:")) << failed.dump(2);
  const auto its_report = api.get("/api/runs/bad_telemetry/analyses/" + id + "/report.html");
  EXPECT_EQ(its_report.status, 422) << its_report.body;
  // Its folder holds the failure's record alone, with the same reason.
  EXPECT_EQ(files_in(server.runs_dir() / "bad_telemetry" / "analyses" / id), std::vector<std::string>{"failed.json"});
  const json record = json::parse(hil::test::slurp(server.runs_dir() / "bad_telemetry" / "analyses" / id / "failed.json"));
  EXPECT_EQ(record["reason"], failed["error"]);
  EXPECT_EQ(record["kind"], "diagnose");
  EXPECT_EQ(leftovers(server.runs_dir()), std::vector<std::string>{});
  EXPECT_EQ(api.get("/api/health").status, 200);
}

TEST(AnalysesApi, ShutdownStopsARunningDiagnosisWhichTheNextServerListsAsFailed) {
  std::string run, diag_id, cmp_id;
  hil::test::TempDir kept;
  {
    ServerProcess server;
    const auto api = server.client();
    run = record_run(api);
    const std::string base = "/api/runs/" + run + "/analyses";
    const auto diag = api.post(base, {{"kind", "diagnose"}, {"model", "nominal"}});
    ASSERT_EQ(diag.status, 202);
    const auto queued = api.post(base, {{"kind", "compare"}, {"model", "nominal"}});
    ASSERT_EQ(queued.status, 202);
    diag_id = diag.json()["analysis"]["id"];
    cmp_id = queued.json()["analysis"]["id"];
    const json d = wait_analysis(api, run, diag_id, [](const json& a) { return a.is_object() && a["state"] != "queued"; });
    ASSERT_EQ(d["state"], "running") << d.dump(2);
    ASSERT_EQ(server.terminate(120s), 0);
    // The diagnosis stopped at a cancel point instead of running its search to the end: its folder
    // holds the failure's record and no result (no analysis.json, diagnosis.json, report or model).
    const auto folder = server.runs_dir() / run / "analyses" / diag_id;
    EXPECT_EQ(files_in(folder), std::vector<std::string>{"failed.json"});
    const json record = json::parse(hil::test::slurp(folder / "failed.json"));
    EXPECT_EQ(record["reason"], "server stopped");
    EXPECT_EQ(record["kind"], "diagnose");
    EXPECT_EQ(record["model"], "nominal");
    EXPECT_TRUE(record["finished_utc"].is_string());
    // The queued compare never ran and is not kept (SERVER.md: queued jobs do not survive).
    EXPECT_FALSE(std::filesystem::exists(server.runs_dir() / run / "analyses" / cmp_id));
    EXPECT_EQ(leftovers(server.runs_dir()), std::vector<std::string>{});
    std::filesystem::copy(server.runs_dir() / run, kept.path() / run, std::filesystem::copy_options::recursive);
  }
  // The next server, on the same run folder, still lists it as failed with the reason.
  ServerProcess next;
  std::filesystem::copy(kept.path() / run, next.runs_dir() / run, std::filesystem::copy_options::recursive);
  const auto api = next.client();
  const json a = analysis_of(api, run, diag_id);
  ASSERT_TRUE(a.is_object()) << api.get("/api/runs/" + run + "/analyses").body;
  EXPECT_EQ(a["state"], "failed");
  EXPECT_EQ(a["error"], "server stopped");
  EXPECT_EQ(a["kind"], "diagnose");
  EXPECT_EQ(api.get("/api/runs/" + run + "/analyses/" + diag_id).json()["analysis"]["error"], "server stopped");
  const auto report = api.get("/api/runs/" + run + "/analyses/" + diag_id + "/report.html");
  EXPECT_EQ(report.status, 422) << report.body;
  EXPECT_EQ(report.json()["detail"], "server stopped");
  // Its id stays taken: the same analysis asked again is a new one.
  const auto again = api.post("/api/runs/" + run + "/analyses", {{"kind", "diagnose"}, {"model", "nominal"}});
  ASSERT_EQ(again.status, 202) << again.body;
  EXPECT_NE(again.json()["analysis"]["id"], diag_id);
}

TEST(AnalysesApi, CtlAnalysesARunListsItsAnalysesAndFetchesTheirFiles) {
  ServerProcess server;
  const auto api = server.client();
  const std::string run = record_run(api);

  // analyse --wait: the compare's headline, as compare.json has it, and the report's URL.
  const CtlResult c = ctl(server, {"analyse", run, "--kind", "compare", "--model", "nominal", "--wait"});
  ASSERT_EQ(c.rc, 0) << c.out;
  const json list = api.get("/api/runs/" + run + "/analyses").json()["analyses"];
  ASSERT_EQ(list.size(), 1u) << list.dump(2);
  const std::string id = list[0]["id"];
  const auto folder = server.runs_dir() / run / "analyses" / id;
  const json compare = json::parse(hil::test::slurp(folder / "compare.json"));
  char fit[64];
  std::snprintf(fit, sizeof fit, "fit %.2f %%", compare["fit_pct"].get<double>());
  EXPECT_TRUE(has(c.out, id + " done: " + fit)) << c.out;
  const std::string url =
      "http://127.0.0.1:" + std::to_string(server.port()) + "/api/runs/" + run + "/analyses/" + id + "/report.html";
  EXPECT_TRUE(has(c.out, "report: " + url)) << c.out;
  EXPECT_EQ(api.get(url.substr(url.find("/api/"))).status, 200);

  // analyses: each with its state and headline.
  const CtlResult l = ctl(server, {"analyses", run});
  ASSERT_EQ(l.rc, 0) << l.out;
  EXPECT_TRUE(has(l.out, id)) << l.out;
  EXPECT_TRUE(has(l.out, "done")) << l.out;
  EXPECT_TRUE(has(l.out, fit)) << l.out;

  // get: an analysis's file, byte for byte.
  const auto out = server.dir() / "fetched_compare.json";
  const CtlResult g = ctl(server, {"get", run, "analyses/" + id + "/compare.json", "--out", out.string()});
  ASSERT_EQ(g.rc, 0) << g.out;
  EXPECT_EQ(hil::test::slurp(out), hil::test::slurp(folder / "compare.json"));

  // The server's refusals, each naming the field it blamed; nothing is queued.
  const CtlResult model = ctl(server, {"analyse", run, "--kind", "compare", "--model", "nomnal"});
  EXPECT_EQ(model.rc, 1) << model.out;
  EXPECT_TRUE(has(model.out, "unknown model (field 'model')")) << model.out;
  EXPECT_TRUE(has(model.out, "did you mean 'nominal'")) << model.out;
  EXPECT_TRUE(has(model.out, "(HTTP 404)")) << model.out;
  const CtlResult kind = ctl(server, {"analyse", run, "--kind", "comparison", "--model", "nominal"});
  EXPECT_EQ(kind.rc, 1) << kind.out;
  EXPECT_TRUE(has(kind.out, "bad field (field 'kind')")) << kind.out;
  EXPECT_TRUE(has(kind.out, "(HTTP 400)")) << kind.out;
  const CtlResult unknown = ctl(server, {"analyse", "nope", "--kind", "compare", "--model", "nominal"});
  EXPECT_EQ(unknown.rc, 1) << unknown.out;
  EXPECT_TRUE(has(unknown.out, "(HTTP 404)")) << unknown.out;
  EXPECT_EQ(api.get("/api/runs/" + run + "/analyses").json()["analyses"].size(), 1u);

  // A failing analysis followed with --wait: exit 3 with the server's reason; its files are refused.
  std::filesystem::create_directory(server.runs_dir() / "bad_telemetry");
  std::filesystem::copy_file(server.runs_dir() / run / "run.json", server.runs_dir() / "bad_telemetry" / "run.json");
  std::ofstream(server.runs_dir() / "bad_telemetry" / "telemetry.csv") << "t_s,theta_cmd_deg,p_meas_mpa\n0.000,1.0,abc\n";
  const CtlResult bad = ctl(server, {"analyse", "bad_telemetry", "--kind", "compare", "--model", "nominal", "--wait"});
  EXPECT_EQ(bad.rc, 3) << bad.out;
  EXPECT_TRUE(has(bad.out, "failed: ")) << bad.out;
  EXPECT_TRUE(has(bad.out, "telemetry.csv:2:")) << bad.out;
  const std::string bad_id = api.get("/api/runs/bad_telemetry/analyses").json()["analyses"][0]["id"];
  const CtlResult bad_get =
      ctl(server, {"get", "bad_telemetry", "analyses/" + bad_id + "/report.html", "--out", (server.dir() / "bad.html").string()});
  EXPECT_EQ(bad_get.rc, 1) << bad_get.out;
  EXPECT_TRUE(has(bad_get.out, "the analysis failed")) << bad_get.out;
  EXPECT_FALSE(std::filesystem::exists(server.dir() / "bad.html"));
  const CtlResult bad_list = ctl(server, {"analyses", "bad_telemetry"});
  EXPECT_EQ(bad_list.rc, 0) << bad_list.out;
  EXPECT_TRUE(has(bad_list.out, "failed")) << bad_list.out;
  EXPECT_TRUE(has(bad_list.out, "telemetry.csv:2:")) << bad_list.out;
}

// A diagnosis holds up to 2.5 x its telemetry.csv in the server's locked memory: one that would
// hold more than --max-diagnose-mb is refused at once with the sizes and what to do instead; a
// smaller one, and a compare of the larger (it streams), are queued. 17 MB allows a file of up to
// 0.4 MB (2.5 x file + 16 MB).
TEST(AnalysesApi, ADiagnosisTooLargeForTheServersMemoryIsRefusedWithTheSizes) {
  ServerProcess server({"--max-diagnose-mb", "17"});
  const auto api = server.client();
  const auto campaign_file = hil::test::source_path("configs/campaigns/gap_step.yaml");
  std::string rows = "t_s,theta_cmd_deg,p_meas_mpa,theta_motor_deg,p_ref_mpa\n";
  for (int k = 0; rows.size() < (std::size_t{1} << 20); ++k) rows += std::to_string(k * 1e-3) + ",10.0,1.0,10.0,1.0\n";
  const std::map<std::string, std::size_t> sizes = {{"small", 100 * 1024}, {"large", rows.size()}};
  for (const auto& [name, bytes] : sizes) {
    const auto dir = server.runs_dir() / name;
    hil::test::write_ended_run(dir, "gap_step", "adaptive", kGapStepYaml, campaign_file, 8);
    const std::string text = rows.substr(0, rows.rfind('\n', bytes) + 1);  // whole lines
    std::ofstream(dir / "telemetry.csv") << text;
  }

  const auto refused = api.post("/api/runs/large/analyses", {{"kind", "diagnose"}, {"model", "nominal"}});
  EXPECT_EQ(refused.status, 422) << refused.body;
  const std::string detail = refused.json().value("detail", "");
  EXPECT_TRUE(has(detail, "telemetry.csv (1 MB)")) << detail;
  EXPECT_TRUE(has(detail, "about 19 MB")) << detail;
  EXPECT_TRUE(has(detail, "allows 17 MB (hilbench serve --max-diagnose-mb)")) << detail;
  EXPECT_FALSE(std::filesystem::exists(server.runs_dir() / "large" / "analyses")) << "nothing was queued or written";

  const auto compare = api.post("/api/runs/large/analyses", {{"kind", "compare"}, {"model", "nominal"}});
  EXPECT_EQ(compare.status, 202) << compare.body;
  const auto small = api.post("/api/runs/small/analyses", {{"kind", "diagnose"}, {"model", "nominal"}});
  EXPECT_EQ(small.status, 202) << small.body;
}

// `ctl get` onto a local disk that fills: the error names the local file (it read as the
// server's disk: "GET ... at 127.0.0.1:PORT: No space left on device"), and the part written is
// removed (a FILE.part ending mid-line was left for ever).
TEST(AnalysesApi, CtlGetOntoAFullDiskNamesTheLocalFileAndLeavesNoPart) {
  ServerProcess server;
  hil::test::SmallDisk disk(server.dir() / "small", "1m");
  if (!disk.mounted()) GTEST_SKIP() << "cannot mount a tmpfs here (not root?): the full-disk case needs its own small disk";
  const auto run = server.runs_dir() / "big";
  hil::test::write_ended_run(run, "gap_step", "adaptive", kGapStepYaml, hil::test::source_path("configs/campaigns/gap_step.yaml"),
                             8);
  std::string rows = "t_s,theta_cmd_deg,p_meas_mpa,theta_motor_deg,p_ref_mpa\n";
  for (int k = 0; rows.size() < (std::size_t{3} << 20); ++k) rows += std::to_string(k * 1e-3) + ",10.0,1.0,10.0,1.0\n";
  std::ofstream(run / "telemetry.csv") << rows;

  const auto out = server.dir() / "small" / "t.csv";
  const CtlResult g = ctl(server, {"get", "big", "telemetry.csv", "--out", out.string()});
  EXPECT_EQ(g.rc, 1) << g.out;
  EXPECT_TRUE(has(g.out, out.string() + ": cannot write the download of /api/runs/big/telemetry.csv: No space left on device"))
      << g.out;
  EXPECT_FALSE(has(g.out, "at 127.0.0.1")) << g.out;
  EXPECT_FALSE(std::filesystem::exists(out.string() + ".part"));
  EXPECT_FALSE(std::filesystem::exists(out));
  // The same file onto a disk with room: whole.
  const auto roomy = server.dir() / "t.csv";
  const CtlResult ok = ctl(server, {"get", "big", "telemetry.csv", "--out", roomy.string()});
  ASSERT_EQ(ok.rc, 0) << ok.out;
  EXPECT_EQ(hil::test::slurp(roomy), rows);
}
