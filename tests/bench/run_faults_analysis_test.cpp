// Bench runs diagnosed as bench runs (issue 49): a run served by the real `hilbench serve` on the
// sim rig, the nominal plant, with an operator's injection through the API (a sensor stuck, a
// dropout that trips the watchdog and ends in the safe state, a bias, extra noise; a gap change),
// diagnosed on the job worker against its own plant. The fault's rows are left out and named, the
// gap change is an input of the replay: nothing is missing. The same telemetry without its run's
// record (copied alone) is compared by `hilbench compare` as a process: there the injection is a
// misfit well above the noise, so the record is what makes the verdict.
#include <gtest/gtest.h>

#include <string>

#include "server_process.hpp"

using namespace std::chrono_literals;
using nlohmann::json;

namespace {

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// 10 s of the adaptive compensator on the nominal plant (gap 1 deg, constant), 2 kPa noise.
const std::string kCampaign = R"(name: faults
description: the nominal plant, for an operator's injections
plant: ../plant/nominal.yaml
duration_s: 10
period_ms: 1
seed: 3
sensor_noise_kpa: 2.0
reference:
  initial_mpa: 1.0
  profile:
    - square: {from_s: 0.5, half_period_s: 1.0, low_mpa: 1.0, high_mpa: 1.5}
gap:
  initial_deg: 1.0
runs:
  - name: adaptive
    compensation: adaptive
)";

struct Injection {
  std::string route;  // /api/inject/...
  json body;
  std::string note;  // a part of the run note it must give
};

// Runs the campaign at 4x, injects at 3 s of loop time, and returns the run's id.
std::string run_with(const hil::bench::ApiClient& api, const Injection& inj) {
  const auto started = api.post("/api/start", {{"campaign_yaml", kCampaign}, {"speed", 4}});
  if (started.status != 202) throw std::runtime_error("start: " + started.body);
  hil::test::wait_status(
      api, [](const json& s) { return s["state"] == "running" && hil::test::status_t(s) > 3.0; }, 60s);
  const auto r = api.post(inj.route, inj.body);
  if (r.status != 200 && r.status != 202) throw std::runtime_error(inj.route + ": " + r.body);
  const json s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle" && x["last"].is_object(); }, 120s);
  if (!s["last"].is_object()) throw std::runtime_error("the run did not end: " + s.dump());
  return api.get("/api/runs").json()["runs"][0]["id"];
}

json analyse(const hil::bench::ApiClient& api, const std::string& run, const std::string& kind) {
  const auto posted = api.post("/api/runs/" + run + "/analyses", {{"kind", kind}, {"model", "nominal"}});
  if (posted.status != 202) throw std::runtime_error("analyse: " + posted.body);
  const std::string id = posted.json()["analysis"]["id"];
  const auto end = std::chrono::steady_clock::now() + 300s;
  while (std::chrono::steady_clock::now() < end) {
    const json list = api.get("/api/runs/" + run + "/analyses").json();  // kept: the loop refers into it
    for (const auto& a : list["analyses"])
      if (a["id"] == id && (a["state"] == "done" || a["state"] == "failed")) return a;
    std::this_thread::sleep_for(50ms);
  }
  throw std::runtime_error("the analysis did not finish");
}

// `hilbench compare` of the run's telemetry copied alone into a folder of its own.
json compare_without_record(const hil::test::ServerProcess& server, const std::string& run, const std::string& name) {
  const auto dir = server.dir() / ("bare_" + name);
  std::filesystem::create_directories(dir);
  std::filesystem::copy_file(server.runs_dir() / run / "telemetry.csv", dir / "telemetry.csv");
  const pid_t pid = hil::test::spawn(
      {hil::test::hilbench_exe(), "compare", "--model", hil::test::source_path("configs/plant/nominal.yaml").string(), "--data",
       (dir / "telemetry.csv").string(), "--out", (dir / "out").string(), "--quiet"},
      dir / "cli.log");
  if (hil::test::wait_exit(pid, 120s) != 0) throw std::runtime_error("compare: " + hil::test::slurp(dir / "cli.log"));
  return json::parse(hil::test::slurp(dir / "out" / "compare.json"));
}

}  // namespace

TEST(RunFaultsAnalysis, EachInjectionIsLeftOutOrReplayedAndNothingIsMissing) {
  hil::test::ServerProcess server;
  const auto api = server.client();
  const std::vector<std::pair<std::string, Injection>> cases = {
      {"stuck", {"/api/inject/sensor", {{"mode", "stuck"}, {"duration_s", 3}}, "left out of the fit: sensor stuck"}},
      {"bias",
       {"/api/inject/sensor", {{"mode", "bias"}, {"bias_kpa", 60}, {"duration_s", 3}}, "left out of the fit: sensor bias"}},
      {"noise",
       {"/api/inject/sensor", {{"mode", "noise"}, {"rms_kpa", 40}, {"duration_s", 3}}, "left out of the fit: sensor noise"}},
      // Three missed reads in a row trip the watchdog: the safe state to the end is left out too.
      {"dropout", {"/api/inject/sensor", {{"mode", "dropout"}, {"duration_s", 3}}, "left out of the fit: sensor dropout"}},
      {"gap", {"/api/inject/gap", {{"gap_deg", 2.5}}, "gap 2.5 deg from"}},
  };
  for (const auto& [name, inj] : cases) {
    SCOPED_TRACE(name);
    const std::string run = run_with(api, inj);
    const json a = analyse(api, run, "diagnose");
    ASSERT_EQ(a["state"], "done") << a.dump(2);
    const json& r = a["result"];
    EXPECT_EQ(r["verdict"], "nothing_missing") << r.dump(2);
    std::string notes;
    for (const auto& n : r["run_notes"]) notes += n.get<std::string>() + "\n";
    EXPECT_TRUE(has(notes, inj.note)) << notes;
    if (name == "gap") {
      EXPECT_EQ(r["rows_left_out"], 0) << notes;
    } else {
      // The fault's rows, named and counted: 3 s at 1 kHz (a dropout trips the watchdog at its third
      // missed read, and the run ends after the safe state's hold: a few hundred rows).
      EXPECT_GE(r["rows_left_out"].get<int>(), name == "dropout" ? 100 : 2900) << notes;
      EXPECT_TRUE(has(notes, "rows left out")) << notes;
    }
    if (name == "dropout") {
      EXPECT_TRUE(has(notes, "left out of the fit: trip: watchdog (safety)")) << notes;
      continue;  // held readings and a safe state: no misfit to show without the record
    }
    // The same rows without the record: the injection is a misfit the nominal model cannot make.
    const json bare = compare_without_record(server, run, name);
    EXPECT_GT(bare["rmse_kpa"].get<double>(), 1.5 * bare["noise_sigma_kpa"].get<double>()) << bare.dump().substr(0, 600);
    EXPECT_EQ(bare["rows_left_out"], 0);
  }
}
