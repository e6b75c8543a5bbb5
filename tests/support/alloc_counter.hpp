// Counts global operator new calls, so tests can prove a real-time path allocates nothing.
// Include in exactly one .cpp of a test binary (it replaces the global allocation functions).
#pragma once

#include <atomic>
#include <cstdlib>
#include <new>

namespace hil::test {
inline std::atomic<long> g_allocations{0};
inline thread_local long t_allocations = 0;  // this thread's: other threads (I/O, emulators) may allocate
inline long allocations() { return g_allocations.load(); }
inline long thread_allocations() { return t_allocations; }
}  // namespace hil::test

void* operator new(std::size_t n) {
  hil::test::g_allocations.fetch_add(1, std::memory_order_relaxed);
  ++hil::test::t_allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
