// A bounded lock-free ring for one producer thread and one consumer thread: the real-time loop
// pushes telemetry rows and events, the recorder pops them. Memory is allocated once, in the
// constructor; a push never blocks and never allocates: when the ring is full it fails, and the
// producer counts the loss (the ring itself never drops silently).
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>
#include <type_traits>
#include <utility>

namespace hil::bench {

template <class T>
class SpscRing {
  static_assert(std::is_trivially_copyable_v<T>, "the ring carries plain data");

 public:
  // Capacity is rounded up to a power of two. Setup: allocates (and touches every page).
  explicit SpscRing(std::size_t capacity) : mask_(round_up(capacity) - 1), slots_(std::make_unique<T[]>(mask_ + 1)) {}
  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;

  // Producer only. Real-time safe. False when full (nothing written).
  bool try_push(const T& value) noexcept {
    T* slot = claim();
    if (slot == nullptr) return false;
    *slot = value;
    publish();
    return true;
  }

  // Producer only, real-time safe: the slot the next push fills, for a producer that writes its
  // value in place over a while rather than copying it in at once; nullptr when full. The
  // consumer sees nothing of it before publish(). Until then, claim() returns the same slot.
  T* claim() noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_cache_ > mask_) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      if (head - tail_cache_ > mask_) return nullptr;
    }
    return &slots_[head & mask_];
  }
  // Producer only: hands the claimed slot to the consumer (call only after claim() gave one).
  // The producer may still read it; only the consumer frees it.
  void publish() noexcept { head_.store(head_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }

  // Consumer only. Copies up to max values into out; returns how many.
  std::size_t pop(T* out, std::size_t max) noexcept {
    return consume(max, [&out](const T& value) noexcept { *out++ = value; });
  }

  // Consumer only. Hands up to max values to f(const T&) where they lie, then frees their slots;
  // returns how many. For a consumer that only reads each value once: no copy out.
  template <class F>
  std::size_t consume(std::size_t max, F&& f) noexcept(noexcept(f(std::declval<const T&>()))) {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    std::size_t n = head_.load(std::memory_order_acquire) - tail;
    if (n > max) n = max;
    for (std::size_t i = 0; i < n; ++i) f(static_cast<const T&>(slots_[(tail + i) & mask_]));
    tail_.store(tail + n, std::memory_order_release);
    return n;
  }

  std::size_t capacity() const noexcept { return mask_ + 1; }
  // Either thread; exact only when the other side is idle.
  std::size_t size() const noexcept { return head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire); }

 private:
  static std::size_t round_up(std::size_t n) {
    std::size_t p = 1;
    while (p < n) p <<= 1;
    return p;
  }

  const std::size_t mask_;
  std::unique_ptr<T[]> slots_;
  alignas(64) std::atomic<std::size_t> head_{0};  // written by the producer
  std::size_t tail_cache_ = 0;                    // producer's last view of tail_
  alignas(64) std::atomic<std::size_t> tail_{0};  // written by the consumer
};

}  // namespace hil::bench
