// The server's job worker (bench/src/server/jobs.hpp) on its own: one job at a time in submission
// order, a bounded queue, a throwing job failed with its message, waiters told once, and stop()
// failing what waits while the running job ends whole. Every wait is for a state, none for a time.
#include <gtest/gtest.h>

#include <atomic>
#include <condition_variable>
#include <future>

#include "server/analyses.hpp"
#include "server/jobs.hpp"
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
  q.submit(job("a"), [&](const JobQueue::Progress& progress) {
    progress(0.5);
    gate.wait();
    note("a");
    return json{{"n", 1}};
  });
  gate.wait_reached();
  EXPECT_EQ(q.find("r", "a")->state, JobState::running);
  EXPECT_DOUBLE_EQ(q.find("r", "a")->progress, 0.5);
  q.submit(job("b"), [&](const JobQueue::Progress&) -> json { throw std::runtime_error("telemetry.csv:2:3: not a number"); });
  q.submit(job("c"), [&](const JobQueue::Progress&) {
    note("c");
    return json{{"n", 3}};
  });
  EXPECT_THROW(q.submit(job("d"), [](const JobQueue::Progress&) { return json(); }), JobRefused);
  EXPECT_THROW(q.submit(job("a"), [](const JobQueue::Progress&) { return json(); }), JobRefused) << "the queue is still full";
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
  q.submit(job("running"), [&](const JobQueue::Progress&) {
    gate.wait();
    return json{{"whole", true}};
  });
  q.submit(job("waiting"), [&](const JobQueue::Progress&) {
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
  EXPECT_EQ(r.result["whole"], true);
  EXPECT_FALSE(second_ran);
  EXPECT_THROW(q.submit(job("late"), [](const JobQueue::Progress&) { return json(); }), JobRefused);
  q.stop("again");  // idempotent
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
