// The server's job worker (bench/src/server/jobs.hpp) on its own: one job at a time in submission
// order, a bounded queue, a throwing job failed with its message, waiters told once, stop()
// failing what waits and raising the running job's cancel flag (a job that ignores it ends whole,
// one that looks at it gives up), failed analyses recorded in their folder, a report read in
// chunks and stopped between them. Every wait is for a state, none for a time.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <future>
#include <map>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/campaign/run_report.hpp"
#include "server/analyses.hpp"
#include "server/jobs.hpp"
#include "run_folder.hpp"
#include "temp_file.hpp"

using hil::bench::JobQueue;
using hil::bench::JobRefused;
using hil::bench::JobState;
using hil::bench::JobStatus;
using nlohmann::json;

namespace {

JobStatus job(const std::string& id) {
  JobStatus s;
  s.run = "r";
  s.id = id;
  s.kind = "compare";
  return s;
}

// A gate a job waits at until the test opens it.
struct Gate {
  std::mutex m;
  std::condition_variable cv;
  bool open = false, reached = false;
  void wait() {
    std::unique_lock l(m);
    reached = true;
    cv.notify_all();
    cv.wait(l, [this] { return open; });
  }
  void wait_reached() {
    std::unique_lock l(m);
    cv.wait(l, [this] { return reached; });
  }
  void release() {
    std::lock_guard l(m);
    open = true;
    cv.notify_all();
  }
};

std::future<JobStatus> finished(JobQueue& q, const std::string& id) {
  auto p = std::make_shared<std::promise<JobStatus>>();
  auto f = p->get_future();
  EXPECT_TRUE(q.when_finished("r", id, [p](const JobStatus& s) { p->set_value(s); }));
  return f;
}

}  // namespace

TEST(JobQueue, RunsInOrderBoundsTheQueueAndFailsAThrowingJobWithItsMessage) {
  JobQueue q(2);
  Gate gate;
  std::vector<std::string> order;
  std::mutex order_m;
  auto note = [&](const std::string& id) {
    std::lock_guard l(order_m);
    order.push_back(id);
  };
  q.submit(job("a"), [&](const JobQueue::Progress& progress, const std::atomic<bool>&) {
    progress(0.5);
    gate.wait();
    note("a");
    return json{{"n", 1}};
  });
  gate.wait_reached();
  EXPECT_EQ(q.find("r", "a")->state, JobState::running);
  EXPECT_DOUBLE_EQ(q.find("r", "a")->progress, 0.5);
  q.submit(job("b"), [&](const JobQueue::Progress&, const std::atomic<bool>&) -> json {
    throw std::runtime_error("telemetry.csv:2:3: not a number");
  });
  q.submit(job("c"), [&](const JobQueue::Progress&, const std::atomic<bool>&) {
    note("c");
    return json{{"n", 3}};
  });
  EXPECT_THROW(q.submit(job("d"), [](const JobQueue::Progress&, const std::atomic<bool>&) { return json(); }), JobRefused);
  EXPECT_THROW(q.submit(job("a"), [](const JobQueue::Progress&, const std::atomic<bool>&) { return json(); }), JobRefused)
      << "the queue is still full";
  EXPECT_EQ(q.find("r", "b")->state, JobState::queued);
  auto fa = finished(q, "a"), fb = finished(q, "b"), fc = finished(q, "c");
  gate.release();
  const JobStatus a = fa.get(), b = fb.get(), c = fc.get();
  EXPECT_EQ(a.state, JobState::done);
  EXPECT_EQ(a.result["n"], 1);
  EXPECT_EQ(b.state, JobState::failed);
  EXPECT_EQ(b.error, "telemetry.csv:2:3: not a number");
  EXPECT_EQ(c.state, JobState::done);
  EXPECT_EQ(order, (std::vector<std::string>{"a", "c"}));
  EXPECT_EQ(q.of_run("r").size(), 3u);
  EXPECT_EQ(q.of_run("other").size(), 0u);
  // A finished job's waiter is told at once; a forgotten job is unknown.
  EXPECT_EQ(finished(q, "b").get().state, JobState::failed);
  q.forget("r", "b");
  EXPECT_FALSE(q.find("r", "b"));
  EXPECT_FALSE(q.when_finished("r", "b", [](const JobStatus&) {}));
}

TEST(JobQueue, StopFailsTheWaitingJobsAndLetsTheRunningOneEnd) {
  JobQueue q(4);
  Gate gate;
  std::atomic<bool> second_ran{false};
  q.submit(job("running"), [&](const JobQueue::Progress&, const std::atomic<bool>& cancel) {
    const bool before = cancel.load();
    gate.wait();
    return json{{"whole", true}, {"cancel_before", before}, {"cancel_after", cancel.load()}};
  });
  q.submit(job("waiting"), [&](const JobQueue::Progress&, const std::atomic<bool>&) {
    second_ran = true;
    return json();
  });
  gate.wait_reached();
  auto fr = finished(q, "running"), fw = finished(q, "waiting");
  std::thread stopper([&] { q.stop("the server is shutting down"); });
  EXPECT_EQ(fw.get().error, "the server is shutting down; the job did not run");
  gate.release();
  stopper.join();
  const JobStatus r = fr.get();
  EXPECT_EQ(r.state, JobState::done);
  EXPECT_EQ(r.result["whole"], true) << "a job without a cancel point ends whole";
  EXPECT_EQ(r.result["cancel_before"], false);
  EXPECT_EQ(r.result["cancel_after"], true) << "the running job was asked to stop before the waiting ones were failed";
  EXPECT_FALSE(second_ran);
  EXPECT_THROW(q.submit(job("late"), [](const JobQueue::Progress&, const std::atomic<bool>&) { return json(); }), JobRefused);
  q.stop("again");  // idempotent
}

TEST(JobQueue, CancelReturnsAtOnceAndTheRunningJobStopsAtItsCancelPoint) {
  JobQueue q(4);
  Gate gate;
  std::atomic<int> units{0};
  // A job of many units that looks at the flag between them, as an analysis does.
  q.submit(job("long"), [&](const JobQueue::Progress&, const std::atomic<bool>& cancel) -> json {
    for (int i = 0; i < 1000000; ++i) {
      if (cancel.load()) throw std::runtime_error("stopped after " + std::to_string(i) + " units");
      if (i == 3) gate.wait();
      ++units;
    }
    return json{{"whole", true}};
  });
  gate.wait_reached();
  auto f = finished(q, "long");
  q.cancel("the server is shutting down");  // does not wait: the job is parked at the gate
  EXPECT_EQ(q.find("r", "long")->state, JobState::running);
  EXPECT_THROW(q.submit(job("late"), [](const JobQueue::Progress&, const std::atomic<bool>&) { return json(); }), JobRefused);
  gate.release();
  const JobStatus s = f.get();
  EXPECT_EQ(s.state, JobState::failed);
  EXPECT_EQ(s.error, "stopped after 4 units");
  EXPECT_EQ(units.load(), 4);
  q.stop("the server is shutting down");
}

TEST(JobLeftovers, AStartRemovesHalfMadeReportsAndAnalysesOnly) {
  hil::test::TempDir dir;
  const auto run = dir.path() / "20261126T000000Z_c_r";
  std::filesystem::create_directories(run / "analyses" / ".compare_nominal_1.tmp");
  std::filesystem::create_directories(run / "analyses" / "compare_nominal_2");
  std::ofstream(run / "analyses" / ".compare_nominal_1.tmp" / "report.html") << "<html>half";
  std::ofstream(run / "analyses" / "compare_nominal_2" / "report.html") << "<html>whole</html>";
  std::ofstream(run / "report.html.tmp") << "<html>half";
  std::ofstream(run / "telemetry.csv") << "t_s\n";
  EXPECT_EQ(hil::bench::remove_job_leftovers(dir.path()), 2u);
  EXPECT_FALSE(std::filesystem::exists(run / "analyses" / ".compare_nominal_1.tmp"));
  EXPECT_FALSE(std::filesystem::exists(run / "report.html.tmp"));
  EXPECT_TRUE(std::filesystem::exists(run / "analyses" / "compare_nominal_2" / "report.html"));
  EXPECT_TRUE(std::filesystem::exists(run / "telemetry.csv"));
  // The next id skips both a finished folder and a name a job in flight holds.
  EXPECT_EQ(hil::bench::next_analysis_id(run, "compare", "nominal", {"compare_nominal_1"}), "compare_nominal_3");
  EXPECT_EQ(hil::bench::next_analysis_id(run, "diagnose", "nominal", {}), "diagnose_nominal_1");
  EXPECT_EQ(hil::bench::remove_job_leftovers(dir.path() / "missing"), 0u);
}

TEST(AnalysisJob, AFailureIsRecordedInItsFolderAndListedAfterARestart) {
  hil::test::TempDir dir;
  const auto run = dir.path() / "20261126T000000Z_c_r";
  std::filesystem::create_directories(run);
  hil::bench::AnalysisSpec spec;
  spec.run_dir = run;
  spec.model = "nominal";
  spec.model_file = hil::test::source_path("configs/plant/nominal.yaml");
  const auto no_progress = [](double) {};

  // Cancelled before its first unit of work: "server stopped", no result, no temporary.
  spec.kind = "diagnose";
  spec.id = "diagnose_nominal_1";
  const std::atomic<bool> cancel{true};
  try {
    hil::bench::run_analysis(spec, no_progress, &cancel);
    ADD_FAILURE() << "a cancelled analysis returned";
  } catch (const std::exception& e) {
    EXPECT_STREQ(e.what(), hil::bench::kServerStopped);
  }
  // A run without telemetry.csv fails with the reader's reason.
  spec.kind = "compare";
  spec.id = "compare_nominal_1";
  std::string reason;
  try {
    hil::bench::run_analysis(spec, no_progress);
    ADD_FAILURE() << "an analysis of a missing file returned";
  } catch (const std::exception& e) {
    reason = e.what();
  }
  EXPECT_NE(reason.find("telemetry.csv"), std::string::npos) << reason;

  std::vector<std::string> files;
  for (const auto& e : std::filesystem::recursive_directory_iterator(run / "analyses"))
    files.push_back(std::filesystem::relative(e.path(), run / "analyses").string());
  std::sort(files.begin(), files.end());
  EXPECT_EQ(files, (std::vector<std::string>{"compare_nominal_1", "compare_nominal_1/failed.json", "diagnose_nominal_1",
                                             "diagnose_nominal_1/failed.json"}))
      << "each failure is its folder with failed.json alone";

  // What a restarted server lists, from the folders alone.
  const auto list = hil::bench::finished_analyses(run);
  ASSERT_EQ(list.size(), 2u);
  std::map<std::string, json> by_id;
  for (const auto& a : list) by_id[a.value("id", "")] = a;
  EXPECT_EQ(by_id["diagnose_nominal_1"]["state"], "failed");
  EXPECT_EQ(by_id["diagnose_nominal_1"]["error"], "server stopped");
  EXPECT_EQ(by_id["diagnose_nominal_1"]["kind"], "diagnose");
  EXPECT_EQ(by_id["diagnose_nominal_1"]["model"], "nominal");
  EXPECT_TRUE(by_id["diagnose_nominal_1"]["finished_utc"].is_string());
  EXPECT_EQ(by_id["compare_nominal_1"]["state"], "failed");
  EXPECT_EQ(by_id["compare_nominal_1"]["error"], reason);
  // The failed ids stay taken: the next analysis is a new one.
  EXPECT_EQ(hil::bench::next_analysis_id(run, "diagnose", "nominal", {}), "diagnose_nominal_2");
}

namespace {

// A run folder as `hilbench serve` leaves it, for a 70 s campaign (70 000 rows: more than one of
// the reader's 65 536-row chunks): run.json with the campaign's snapshot, and the telemetry the
// simulation of the same campaign writes (the recorder's schema). Returns the simulation's summary.
hil::bench::RunSummary record_long_run(const std::filesystem::path& out, const std::filesystem::path& run_dir) {
  const std::string yaml =
      "name: long_review\n"
      "plant: ../plant/nominal.yaml\n"
      "duration_s: 70\n"
      "period_ms: 1\n"
      "seed: 3\n"
      "sensor_noise_kpa: 2.0\n"
      "reference:\n"
      "  initial_mpa: 1.0\n"
      "  profile:\n"
      "    - square: {from_s: 0.5, half_period_s: 2.0, low_mpa: 1.0, high_mpa: 1.5}\n"
      "gap:\n"
      "  initial_deg: 1.0\n"
      "runs:\n"
      "  - name: adaptive\n"
      "    compensation: adaptive\n"
      "    initial_gap_deg: 0\n";
  const auto campaigns = hil::test::source_path("configs/campaigns");
  const hil::bench::Campaign c = hil::bench::load_campaign_text(yaml, "long_review.yaml", campaigns);
  hil::bench::SimOptions sim;
  sim.out_dir = out;
  sim.progress = false;
  const auto outcome = hil::bench::run_campaign(c, sim);
  hil::test::write_ended_run(run_dir, c.name, "adaptive", yaml, campaigns / "long_review.yaml", 70);
  std::filesystem::copy_file(outcome.dir / "adaptive" / "telemetry.csv", run_dir / "telemetry.csv");
  return outcome.runs.front().summary;
}

}  // namespace

// A report reads the run's telemetry one chunk of rows at a time (its memory does not grow with
// the run): the metrics across the chunks' seams are the simulation's, and it says how far it is.
TEST(ReportJob, ReadsTheTelemetryInChunksAndSaysHowFarItIs) {
  hil::test::TempDir dir;
  const auto run = dir.path() / "20261127T050000Z_long_review_adaptive";
  const hil::bench::RunSummary sim = record_long_run(dir.path() / "sim", run);

  std::vector<double> progress;
  hil::bench::RunReportOptions options;
  options.progress = [&](double f) { progress.push_back(f); };
  const auto runs = hil::bench::write_run_report({run}, dir.path() / "review.html", options);
  ASSERT_EQ(runs.size(), 1u);
  const auto& got = runs.front().digest.summary;
  EXPECT_NEAR(got.iae_mpa_s, sim.iae_mpa_s, 1e-3 * sim.iae_mpa_s);
  EXPECT_EQ(got.touch_state_changes, sim.touch_state_changes);
  ASSERT_EQ(got.reversals.size(), sim.reversals.size());
  ASSERT_GE(sim.reversals.size(), 30u);
  for (std::size_t i = 0; i < sim.reversals.size(); ++i) {
    EXPECT_NEAR(got.reversals[i].stall_s, sim.reversals[i].stall_s, 0.005) << "reversal " << i;
    EXPECT_NEAR(got.reversals[i].gap_est_deg, sim.reversals[i].gap_est_deg, 1e-4) << "reversal " << i;
  }
  ASSERT_EQ(progress.size(), 2u) << "one call a chunk: 65 536 rows, then 4 464";
  EXPECT_GT(progress[0], 0.9);
  EXPECT_LT(progress[0], 1.0);
  EXPECT_EQ(progress[1], 1.0);
  EXPECT_GT(std::filesystem::file_size(dir.path() / "review.html"), 10000u);
}

// Stopped between chunks (a server shutting down): nothing is written; the server's job says
// "server stopped" and leaves no report.html.tmp.
TEST(ReportJob, ACancelStopsBetweenChunksAndWritesNothing) {
  hil::test::TempDir dir;
  const auto run = dir.path() / "20261127T050000Z_long_review_adaptive";
  record_long_run(dir.path() / "sim", run);

  std::atomic<bool> cancel{false};
  int chunks = 0;
  hil::bench::RunReportOptions options;
  options.cancel = &cancel;
  options.progress = [&](double) {
    ++chunks;
    cancel = true;  // raised while the first chunk is being read
  };
  EXPECT_THROW(hil::bench::write_run_report({run}, dir.path() / "review.html", options), hil::bench::Cancelled);
  EXPECT_EQ(chunks, 1);
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "review.html"));

  try {
    hil::bench::make_run_report(
        run, [](double) {}, &cancel);
    ADD_FAILURE() << "a cancelled report returned";
  } catch (const std::exception& e) {
    EXPECT_STREQ(e.what(), hil::bench::kServerStopped);
  }
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(run)) files.push_back(e.path().filename().string());
  std::sort(files.begin(), files.end());
  EXPECT_EQ(files, (std::vector<std::string>{"run.json", "telemetry.csv"}));

  cancel = false;  // the next request after a restart makes it
  const json made = hil::bench::make_run_report(
      run, [](double) {}, &cancel);
  EXPECT_EQ(made["outcome"], "completed");
  EXPECT_TRUE(hil::bench::run_report_current(run));
}
