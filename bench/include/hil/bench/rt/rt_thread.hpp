// Real-time thread setup and pacing: SCHED_FIFO, CPU affinity and locked memory when the
// system permits them (with a warning and the normal scheduler when it does not), and a loop
// woken on absolute CLOCK_MONOTONIC deadlines. Setup calls allocate and may fail; run_paced is
// the real-time part.
#pragma once

#include <chrono>
#include <string>
#include <thread>

#include "hil/bench/rt/rt_loop.hpp"

namespace hil::bench {

// What a thread got, for the operator and run.json.
struct RtSetup {
  bool fifo = false;
  int priority = 0;
  int cpu = -1;                  // pinned to this CPU, -1 = not pinned
  std::string warning;           // empty when everything asked for was granted
  std::string describe() const;  // "SCHED_FIFO 80, CPU 1" / "SCHED_OTHER (...)"
};

// Applies SCHED_FIFO at `priority` (0: leave the normal scheduler) and pins to `cpu` (-1: no
// pinning) on `thread`. Never throws: whatever is refused lands in the warning.
RtSetup make_realtime(std::thread& thread, int priority, int cpu);

// mlockall(MCL_CURRENT | MCL_FUTURE): page faults would otherwise stall the loop. Returns an
// empty string when granted, else the warning.
std::string lock_memory();

// A PM QoS request on /dev/cpu_dma_latency, held while the object lives: CPUs stay out of idle
// states slower to leave than `max_us` (cyclictest makes the same request). Refused (not root):
// a warning, nothing else.
class CpuLatencyRequest {
 public:
  explicit CpuLatencyRequest(int max_us);
  ~CpuLatencyRequest();
  CpuLatencyRequest(const CpuLatencyRequest&) = delete;
  CpuLatencyRequest& operator=(const CpuLatencyRequest&) = delete;
  const std::string& warning() const { return warning_; }

 private:
  int fd_ = -1;
  std::string warning_;
};

// While it lives, the calling thread runs SCHED_FIFO at `priority` (0: unchanged), so threads it
// starts inherit that (the device clients' and emulators' I/O threads, which the library creates
// without asking); the destructor restores the thread's own policy. Refused: a warning.
class ScopedRealtime {
 public:
  explicit ScopedRealtime(int priority);
  ~ScopedRealtime();
  ScopedRealtime(const ScopedRealtime&) = delete;
  ScopedRealtime& operator=(const ScopedRealtime&) = delete;
  const std::string& warning() const { return warning_; }

 private:
  bool changed_ = false;
  int policy_ = 0;
  int priority_ = 0;
  std::string warning_;
};

// Takes `cpu` out of the calling thread's affinity when other CPUs remain (helper threads keep
// off the loop's CPU). -1: nothing. Setup; never throws.
void keep_off_cpu(int cpu) noexcept;

// Touches `bytes` of stack so the loop never faults a stack page in. Real-time safe.
void prefault_stack(std::size_t bytes = 256 * 1024) noexcept;

// Sleeps until `deadline` on CLOCK_MONOTONIC (absolute, so errors do not accumulate). Real-time safe.
void sleep_until(Clock::time_point deadline) noexcept;

// Runs `loop` until the run ends: wakes at start, start + period, ..., calls cycle/finish_cycle.
// A deadline that has passed when a period ends is skipped (counted), as cyclictest does: after
// a stall the loop resumes on the period grid instead of running late periods back to back.
// Real-time safe.
void run_paced(RunLoop& loop, Clock::time_point start) noexcept;

// The pacer's step: the first deadline on the grid after `deadline` that has not passed at
// `end`; `skipped` counts the ones passed over. Real-time safe.
Clock::time_point next_deadline(Clock::time_point deadline, Clock::duration period, Clock::time_point end,
                                std::int64_t& skipped) noexcept;

}  // namespace hil::bench
