// The server's slow work off the io thread: a run's report and the analyses of recorded runs
// (compare, diagnose) take from a tenth of a second to minutes, and the io thread serves every
// request and the telemetry WebSocket. One worker thread runs the jobs in order, one at a time (a
// second one would compete with the first for the two cores the loop's machine typically has,
// not finish sooner); the queue of waiting jobs is bounded, and a submission beyond it is refused
// with the reason (503), never buffered without bound.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

namespace hil::bench {

enum class JobState { queued, running, done, failed };
const char* to_string(JobState s);

struct JobStatus {
  std::string run;    // the run folder's name
  std::string id;     // unique within the run: "report", or an analysis id
  std::string kind;   // report | compare | diagnose
  std::string model;  // the plant model's name (analyses)
  JobState state = JobState::queued;
  double progress = -1;  // 0..1 where the work reports it, else negative
  std::string error;     // failed: why (the exception's message)
  std::string queued_utc, started_utc, finished_utc;
  nlohmann::json result;  // done: what the work returned
  nlohmann::json to_json() const;
};

// Refused submissions: the queue is full, or the server is shutting down.
class JobRefused : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class JobQueue {
 public:
  using Progress = std::function<void(double fraction)>;
  // The work: runs on the worker thread; what it throws fails the job with the message. `cancel`
  // is raised by cancel()/stop(): a long job looks at it between units of work and gives up
  // (analyses.hpp), a short one may ignore it and end.
  using Work = std::function<nlohmann::json(const Progress& progress, const std::atomic<bool>& cancel)>;
  using Finished = std::function<void(const JobStatus& s)>;

  // max_waiting: jobs queued behind the running one; keep_finished: finished jobs remembered for
  // their state (the oldest are forgotten first).
  explicit JobQueue(std::size_t max_waiting, std::size_t keep_finished = 256);
  ~JobQueue();
  JobQueue(const JobQueue&) = delete;
  JobQueue& operator=(const JobQueue&) = delete;

  // Queues `work` under status.run/status.id (which must not name a job already queued or
  // running). Throws JobRefused when max_waiting jobs wait or after stop().
  JobStatus submit(JobStatus status, Work work);
  std::optional<JobStatus> find(const std::string& run, const std::string& id) const;
  std::vector<JobStatus> of_run(const std::string& run) const;  // in submission order
  // Calls `finished` once the job is done or failed: at once (on this thread) if it is already,
  // else on the worker thread (or the thread calling stop()). False for an unknown job.
  bool when_finished(const std::string& run, const std::string& id, Finished finished);
  // Forgets a finished job (a failed report, so that the next request tries again).
  void forget(const std::string& run, const std::string& id);
  // Shutting down, without waiting: later submissions are refused, the queued jobs fail with `why`,
  // and the running job's cancel flag is raised. Idempotent; safe on the io thread.
  void cancel(const std::string& why);
  // cancel(why), then waits for the running job to end (at its next cancel point, or whole when
  // it has none) and stops the worker. Idempotent.
  void stop(const std::string& why);

 private:
  struct Entry {
    JobStatus status;
    Work work;
    std::vector<Finished> waiters;
  };
  void work_loop();
  std::shared_ptr<Entry> find_entry(const std::string& run, const std::string& id) const;

  const std::size_t max_waiting_, keep_finished_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::shared_ptr<Entry>> waiting_;
  std::deque<std::shared_ptr<Entry>> all_;  // every job remembered, in submission order
  bool stopping_ = false;
  std::string stop_reason_;
  std::atomic<bool> cancel_{false};  // raised once by cancel(); the running job's stop request
  std::mutex join_mutex_;            // stop() from two threads joins the worker once
  std::thread worker_;               // last: started once the rest exists
};

}  // namespace hil::bench
