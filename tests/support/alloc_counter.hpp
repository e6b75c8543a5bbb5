// Counts global operator new calls, so tests can prove a real-time path allocates nothing.
// Include in exactly one .cpp of a test binary (it replaces the global allocation functions).
//
// Every replaceable allocation function is replaced, not only the plain ones: the standard
// library reaches the nothrow forms (std::stable_sort's buffer) and the aligned forms
// (over-aligned types), and a memory block must be released by the family that allocated it.
// Replacing only operator new(size_t) and the deletes would free, with std::free, blocks that
// the runtime's own nothrow new allocated: undefined behaviour, and AddressSanitizer reports it
// (alloc-dealloc-mismatch). Here every form allocates with std::malloc or std::aligned_alloc and
// every delete releases with std::free, and every allocating form is counted.
//
// Under AddressSanitizer these replacements take over ASan's own operator new/delete (ASan still
// checks the malloc/free underneath), so the counts stay meaningful in the sanitizer build too.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdlib>
#include <new>

namespace hil::test {
inline std::atomic<long> g_allocations{0};
inline thread_local long t_allocations = 0;  // this thread's: other threads (I/O, emulators) may allocate
inline long allocations() { return g_allocations.load(); }
inline long thread_allocations() { return t_allocations; }

namespace detail {
inline void count_allocation() noexcept {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  ++t_allocations;
}
inline void* allocate(std::size_t n) noexcept {
  count_allocation();
  return std::malloc(n ? n : 1);
}
inline void* allocate(std::size_t n, std::align_val_t al) noexcept {
  count_allocation();
  auto a = static_cast<std::size_t>(al);
  if (a < sizeof(void*)) a = sizeof(void*);
  const std::size_t size = n ? (n + a - 1) / a * a : a;  // aligned_alloc wants a multiple of the alignment
  return std::aligned_alloc(a, size);
}
// Out of line on purpose: GCC 12 sees free() on a pointer from an operator new at an inlined
// call site and warns (-Wmismatched-new-delete), not knowing that every new here is malloc.
[[gnu::noinline]] inline void release(void* p) noexcept { std::free(p); }
}  // namespace detail
}  // namespace hil::test

// Throwing forms.
void* operator new(std::size_t n) {
  if (void* p = hil::test::detail::allocate(n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  if (void* p = hil::test::detail::allocate(n)) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t n, std::align_val_t al) {
  if (void* p = hil::test::detail::allocate(n, al)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t al) {
  if (void* p = hil::test::detail::allocate(n, al)) return p;
  throw std::bad_alloc();
}

// Nothrow forms.
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return hil::test::detail::allocate(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return hil::test::detail::allocate(n); }
void* operator new(std::size_t n, std::align_val_t al, const std::nothrow_t&) noexcept {
  return hil::test::detail::allocate(n, al);
}
void* operator new[](std::size_t n, std::align_val_t al, const std::nothrow_t&) noexcept {
  return hil::test::detail::allocate(n, al);
}

// Every delete: all blocks above come from malloc or aligned_alloc, both released by free.
void operator delete(void* p) noexcept { hil::test::detail::release(p); }
void operator delete[](void* p) noexcept { hil::test::detail::release(p); }
void operator delete(void* p, std::size_t) noexcept { hil::test::detail::release(p); }
void operator delete[](void* p, std::size_t) noexcept { hil::test::detail::release(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { hil::test::detail::release(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { hil::test::detail::release(p); }
void operator delete(void* p, std::align_val_t) noexcept { hil::test::detail::release(p); }
void operator delete[](void* p, std::align_val_t) noexcept { hil::test::detail::release(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { hil::test::detail::release(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { hil::test::detail::release(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { hil::test::detail::release(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { hil::test::detail::release(p); }
