#include "hil/bench/rt/rt_thread.hpp"

#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace hil::bench {

static_assert(std::is_same_v<Clock, std::chrono::steady_clock>, "the loop sleeps on CLOCK_MONOTONIC = steady_clock");

std::string RtSetup::describe() const {
  std::string s = fifo ? "SCHED_FIFO " + std::to_string(priority) : std::string("SCHED_OTHER");
  s += cpu >= 0 ? ", CPU " + std::to_string(cpu) : std::string(", any CPU");
  return s;
}

RtSetup make_realtime(std::thread& thread, int priority, int cpu) {
  RtSetup r;
  const pthread_t h = thread.native_handle();
  if (priority > 0) {
    sched_param sp{};
    sp.sched_priority = priority;
    const int err = pthread_setschedparam(h, SCHED_FIFO, &sp);
    if (err == 0) {
      r.fifo = true;
      r.priority = priority;
    } else {
      r.warning +=
          "SCHED_FIFO " + std::to_string(priority) + " refused (" + std::strerror(err) +
          "; run as root or grant CAP_SYS_NICE / an rtprio limit): the loop runs on the normal scheduler, expect jitter. ";
    }
  }
  if (cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(static_cast<unsigned>(cpu), &set);
    const int err = pthread_setaffinity_np(h, sizeof set, &set);
    if (err == 0) {
      r.cpu = cpu;
    } else {
      r.warning += "CPU affinity " + std::to_string(cpu) + " refused (" + std::strerror(err) + "): the loop may migrate. ";
    }
  }
  if (!r.warning.empty()) r.warning.pop_back();
  return r;
}

std::string lock_memory() {
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) return {};
  return std::string("mlockall refused (") + std::strerror(errno) +
         "; raise RLIMIT_MEMLOCK or run as root): page faults may delay the loop";
}

CpuLatencyRequest::CpuLatencyRequest(int max_us) {
  fd_ = ::open("/dev/cpu_dma_latency", O_WRONLY | O_CLOEXEC);
  const std::int32_t value = max_us;
  if (fd_ < 0 || ::write(fd_, &value, sizeof value) != static_cast<ssize_t>(sizeof value)) {
    warning_ = std::string("/dev/cpu_dma_latency refused (") + std::strerror(errno) +
               "): CPUs may sleep in deep idle states, adding wake-up latency";
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
}

CpuLatencyRequest::~CpuLatencyRequest() {
  if (fd_ >= 0) ::close(fd_);  // closing ends the request
}

ScopedRealtime::ScopedRealtime(int priority) {
  if (priority <= 0) return;
  sched_param old{};
  pthread_getschedparam(pthread_self(), &policy_, &old);
  priority_ = old.sched_priority;
  sched_param sp{};
  sp.sched_priority = priority;
  const int err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
  if (err == 0) {
    changed_ = true;
  } else {
    warning_ = "SCHED_FIFO " + std::to_string(priority) + " for the I/O threads refused (" + std::strerror(err) +
               "): they run on the normal scheduler";
  }
}

ScopedRealtime::~ScopedRealtime() {
  if (!changed_) return;
  sched_param sp{};
  sp.sched_priority = priority_;
  pthread_setschedparam(pthread_self(), policy_, &sp);
}

void keep_off_cpu(int cpu) noexcept {
  if (cpu < 0) return;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (pthread_getaffinity_np(pthread_self(), sizeof set, &set) != 0 || !CPU_ISSET(cpu, &set) || CPU_COUNT(&set) < 2) return;
  CPU_CLR(static_cast<unsigned>(cpu), &set);
  pthread_setaffinity_np(pthread_self(), sizeof set, &set);
}

void prefault_stack(std::size_t bytes) noexcept {
  volatile unsigned char* p = static_cast<unsigned char*>(__builtin_alloca(bytes));
  for (std::size_t i = 0; i < bytes; i += 4096) p[i] = 0;
}

void sleep_until(Clock::time_point deadline) noexcept {
  const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(deadline.time_since_epoch()).count();
  timespec ts{static_cast<time_t>(ns / 1000000000), static_cast<long>(ns % 1000000000)};
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {}
}

void run_paced(RunLoop& loop, Clock::time_point start) noexcept {
  Clock::time_point deadline = start;
  for (;;) {
    sleep_until(deadline);
    const auto woke = Clock::now();
    loop.cycle(deadline, woke);
    const auto end = Clock::now();
    if (!loop.finish_cycle(end)) return;
    std::int64_t skipped = 0;
    deadline = next_deadline(deadline, loop.wall_period(), end, skipped);
    if (skipped > 0) loop.skipped(skipped);
  }
}

Clock::time_point next_deadline(Clock::time_point deadline, Clock::duration period, Clock::time_point end,
                                std::int64_t& skipped) noexcept {
  deadline += period;
  skipped = 0;
  if (deadline < end) {
    skipped = (end - deadline) / period + 1;
    deadline += skipped * period;
  }
  return deadline;
}

}  // namespace hil::bench
