#include "jobs.hpp"

#include <algorithm>
#include <chrono>

#include "hil/bench/server/runner.hpp"

namespace hil::bench {

const char* to_string(JobState s) {
  switch (s) {
    case JobState::queued: return "queued";
    case JobState::running: return "running";
    case JobState::done: return "done";
    case JobState::failed: return "failed";
  }
  return "?";
}

nlohmann::json JobStatus::to_json() const {
  nlohmann::json j = {{"id", id}, {"run", run}, {"kind", kind}, {"state", to_string(state)}, {"queued_utc", queued_utc}};
  if (!model.empty()) j["model"] = model;
  j["progress"] = progress >= 0 ? nlohmann::json(progress) : nlohmann::json(nullptr);
  if (!started_utc.empty()) j["started_utc"] = started_utc;
  if (!finished_utc.empty()) j["finished_utc"] = finished_utc;
  if (state == JobState::failed) j["error"] = error;
  if (state == JobState::done && !result.is_null()) j["result"] = result;
  return j;
}

JobQueue::JobQueue(std::size_t max_waiting, std::size_t keep_finished)
    : max_waiting_(max_waiting), keep_finished_(keep_finished), worker_([this] { work_loop(); }) {}

JobQueue::~JobQueue() { stop("the server is shutting down"); }

std::shared_ptr<JobQueue::Entry> JobQueue::find_entry(const std::string& run, const std::string& id) const {
  for (auto it = all_.rbegin(); it != all_.rend(); ++it) {
    if ((*it)->status.run == run && (*it)->status.id == id) return *it;
  }
  return nullptr;
}

JobStatus JobQueue::submit(JobStatus status, Work work) {
  std::lock_guard lock(mutex_);
  if (stopping_) throw JobRefused(stop_reason_);
  if (waiting_.size() >= max_waiting_) {
    throw JobRefused(std::to_string(waiting_.size()) +
                     " jobs are waiting for the worker (the limit); try again when one has run");
  }
  if (const auto e = find_entry(status.run, status.id);
      e && (e->status.state == JobState::queued || e->status.state == JobState::running)) {
    throw std::logic_error("job " + status.run + "/" + status.id + " is already queued or running");
  }
  status.state = JobState::queued;
  status.queued_utc = utc_iso(std::chrono::system_clock::now());
  auto entry = std::make_shared<Entry>(Entry{std::move(status), std::move(work), {}});
  waiting_.push_back(entry);
  all_.push_back(entry);
  // Forget the oldest finished jobs beyond the limit (queued and running ones are never forgotten).
  std::size_t finished = 0;
  for (const auto& e : all_) finished += e->status.state == JobState::done || e->status.state == JobState::failed;
  for (auto it = all_.begin(); finished > keep_finished_ && it != all_.end();) {
    if ((*it)->status.state == JobState::done || (*it)->status.state == JobState::failed) {
      it = all_.erase(it);
      --finished;
    } else {
      ++it;
    }
  }
  wake_.notify_one();
  return entry->status;
}

std::optional<JobStatus> JobQueue::find(const std::string& run, const std::string& id) const {
  std::lock_guard lock(mutex_);
  if (const auto e = find_entry(run, id)) return e->status;
  return std::nullopt;
}

std::vector<JobStatus> JobQueue::of_run(const std::string& run) const {
  std::lock_guard lock(mutex_);
  std::vector<JobStatus> out;
  for (const auto& e : all_) {
    if (e->status.run == run) out.push_back(e->status);
  }
  return out;
}

bool JobQueue::when_finished(const std::string& run, const std::string& id, Finished finished) {
  std::unique_lock lock(mutex_);
  const auto e = find_entry(run, id);
  if (!e) return false;
  if (e->status.state == JobState::done || e->status.state == JobState::failed) {
    const JobStatus s = e->status;
    lock.unlock();
    finished(s);
    return true;
  }
  e->waiters.push_back(std::move(finished));
  return true;
}

void JobQueue::forget(const std::string& run, const std::string& id) {
  std::lock_guard lock(mutex_);
  std::erase_if(all_, [&](const std::shared_ptr<Entry>& e) {
    return e->status.run == run && e->status.id == id &&
           (e->status.state == JobState::done || e->status.state == JobState::failed);
  });
}

void JobQueue::work_loop() {
  for (;;) {
    std::shared_ptr<Entry> e;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !waiting_.empty(); });
      if (stopping_) return;
      e = waiting_.front();
      waiting_.pop_front();
      e->status.state = JobState::running;
      e->status.started_utc = utc_iso(std::chrono::system_clock::now());
    }
    nlohmann::json result;
    std::string error;
    bool ok = false;
    try {
      result = e->work(
          [this, e](double fraction) {
            std::lock_guard lock(mutex_);
            e->status.progress = std::clamp(fraction, 0.0, 1.0);
          },
          cancel_);
      ok = true;
    } catch (const std::exception& ex) {
      error = ex.what();
    } catch (...) {
      error = "the job failed with an exception that is not a std::exception";
    }
    std::vector<Finished> waiters;
    JobStatus final_status;
    {
      std::lock_guard lock(mutex_);
      e->status.state = ok ? JobState::done : JobState::failed;
      e->status.finished_utc = utc_iso(std::chrono::system_clock::now());
      if (ok) {
        e->status.result = std::move(result);
        e->status.progress = 1;
      } else {
        e->status.error = error;
      }
      e->work = nullptr;
      waiters.swap(e->waiters);
      final_status = e->status;
    }
    for (auto& w : waiters) w(final_status);
  }
}

void JobQueue::cancel(const std::string& why) {
  std::vector<std::pair<Finished, JobStatus>> calls;
  {
    std::lock_guard lock(mutex_);
    if (!stopping_) {
      stopping_ = true;
      stop_reason_ = why;
    }
    cancel_.store(true);
    for (auto& e : waiting_) {
      e->status.state = JobState::failed;
      e->status.error = why + "; the job did not run";
      e->status.finished_utc = utc_iso(std::chrono::system_clock::now());
      e->work = nullptr;
      for (auto& w : e->waiters) calls.emplace_back(std::move(w), e->status);
      e->waiters.clear();
    }
    waiting_.clear();
  }
  wake_.notify_all();
  for (auto& [w, s] : calls) w(s);
}

void JobQueue::stop(const std::string& why) {
  cancel(why);
  // The running job ends first, at its next cancel point or whole: its output is renamed into place
  // or removed, never left half.
  std::lock_guard join_lock(join_mutex_);
  if (worker_.joinable() && worker_.get_id() != std::this_thread::get_id()) worker_.join();
}

}  // namespace hil::bench
