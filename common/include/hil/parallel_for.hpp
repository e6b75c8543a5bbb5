// The one way independent pieces of work run on several threads (a campaign's runs in `hilbench
// sim`, a sweep's points as they are checked and as they run): each index once, handed out in
// increasing order to whichever thread is free, the calling thread among them. Header-only, so
// the body inlines.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#include <type_traits>
#include <vector>

namespace hil {

// Threads for `n` pieces of work: the hardware's (at least one), at most `limit` when given
// (non-zero), never more than n.
inline unsigned worker_threads(std::size_t n, unsigned limit = 0) {
  unsigned t = std::max(1u, std::thread::hardware_concurrency());
  if (limit > 0) t = std::min(t, limit);
  return static_cast<unsigned>(std::max<std::size_t>(1, std::min<std::size_t>(t, n)));
}

// Runs body(state, i) for i in [0, n) on `threads` threads; `state` is what make_state() made once
// per thread, on that thread (a reusable model, a parser), and must not throw (make what may fail
// lazily in body). body returns false (or void: go on) to
// stop the handing out: the indices already started finish, no new one starts. An exception from
// body stops the handing out the same way; once every thread has ended, the exception of the
// lowest index is rethrown, so which error is reported does not depend on the machine.
template <class MakeState, class Body>
void parallel_for(std::size_t n, unsigned threads, MakeState&& make_state, Body&& body) {
  std::atomic<std::size_t> next{0};
  std::atomic<bool> stop{false};
  std::mutex error_mutex;
  std::exception_ptr error;
  std::size_t error_index = n;
  auto worker = [&] {
    auto state = make_state();
    while (!stop.load(std::memory_order_relaxed)) {
      const std::size_t i = next.fetch_add(1);
      if (i >= n) return;
      try {
        if constexpr (std::is_same_v<decltype(body(state, i)), void>) {
          body(state, i);
        } else if (!body(state, i)) {
          stop.store(true);
        }
      } catch (...) {
        std::lock_guard lock(error_mutex);
        if (i < error_index) error = std::current_exception(), error_index = i;
        stop.store(true);
      }
    }
  };
  std::vector<std::thread> pool;
  const unsigned count = static_cast<unsigned>(std::max<std::size_t>(1, std::min<std::size_t>(threads, n)));
  for (unsigned t = 1; t < count; ++t) pool.emplace_back(worker);
  try {
    worker();
  } catch (...) {  // make_state threw on the calling thread: the others still end first
    stop.store(true);
    for (auto& t : pool) t.join();
    throw;
  }
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

// The same without per-thread state: body(i).
template <class Body>
void parallel_for(std::size_t n, unsigned threads, Body&& body) {
  struct None {};
  parallel_for(
      n, threads, [] { return None{}; }, [&body](None&, std::size_t i) { return body(i); });
}

}  // namespace hil
