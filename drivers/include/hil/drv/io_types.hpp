// Plain data exchanged between a real-time loop and a driver's I/O thread, and the lock-free
// single-value mailbox that carries it. Shared with the bench: depends on the standard library only.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <string_view>
#include <type_traits>

namespace hil::drv {

using Clock = std::chrono::steady_clock;
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// What the loop asks of a position drive. Positions are load-side (valve) radians.
struct DriveCommand {
  double target_position_rad = 0.0;
  bool enable = false;  // false: hold switched on, power stage idle
  // A rising edge acknowledges a latched fault: one fault reset if the drive is in fault (a CiA 402
  // drive is held disabled after a fault until then, or until activate()).
  bool fault_reset = false;
};

// How a drive was last switched off (by deactivate(), or by the client itself when its link could
// no longer carry the loop's commands): the path that did it, what asked for it, how long it took
// and the state read back from the drive afterwards (never a stale cyclic reply's). Setup threads only.
struct SwitchOff {
  // "pdo" (the cyclic controlword), "sdo" (0x6040 written, 0x6041 read back by SDO), "nmt_stop"
  // (SDO failed too: the node was stopped), "register" (a Modbus control register); "" none yet.
  std::string path;
  std::string asked_by;  // "deactivate()", or the fault that made the client do it
  double after_ms = -1;  // from the request to the state read back (or the last attempt)
  std::string state;     // as read back; "unknown" when nothing answered
  bool off = false;      // the state read back has the power stage off
};

struct DriveFeedback {
  double position_rad = kNaN;
  double velocity_rad_s = kNaN;  // NaN where the drive does not report it
  std::uint16_t statusword = 0;  // CiA 402 statusword, or the Modbus status register
  bool enabled = false;          // power stage on and following the target
  bool fault = false;            // drive fault, or link fault (heartbeat lost, bus-off): see health()
  bool valid = false;            // false until the first reply
  Clock::time_point rx_time{};   // when the reply arrived (kernel timestamp where there is one)
  std::uint64_t sequence = 0;    // counts replies; unchanged means no news since the last read
};

struct PressureReading {
  double pressure_pa = kNaN;
  bool fault = false;
  bool valid = false;
  Clock::time_point rx_time{};
  std::uint64_t sequence = 0;
};

enum class BusState : std::uint8_t { error_active, error_warning, error_passive, bus_off };

constexpr std::string_view to_string(BusState s) {
  switch (s) {
    case BusState::error_active: return "error-active";
    case BusState::error_warning: return "error-warning";
    case BusState::error_passive: return "error-passive";
    case BusState::bus_off: return "bus-off";
  }
  return "?";
}

// Link and device health as the bench sees it. Fields that do not apply to a device stay zero.
struct DeviceHealth {
  bool connected = false;       // CAN: heartbeats arrive and the bus is not off; Modbus: last request answered
  bool fault = false;           // something the bench must act on; last_error says what
  bool heartbeat_lost = false;  // CAN: no heartbeat within heartbeat_timeout
  // Modbus: the newest request failed (an exception reply, a timeout, a lost link; last_error says
  // how), until a poll goes through. What a stale reading is waiting on.
  bool failing = false;
  BusState bus_state = BusState::error_active;
  std::uint8_t nmt_state = 0xFF;               // CAN: last heartbeat state byte (0x05 operational); 0xFF unknown
  std::uint16_t statusword = 0;                // last statusword / status register
  Clock::time_point last_heartbeat{};          // CAN: last heartbeat; Modbus: last good reply
  std::chrono::nanoseconds heartbeat_age{-1};  // filled by health(): now - last_heartbeat; -1 never
  std::chrono::nanoseconds heartbeat_timeout{0};
  std::uint64_t tx_frames = 0, rx_frames = 0;     // CAN frames / Modbus requests and replies
  std::uint64_t tx_failed = 0;                    // frames the interface refused, requests that failed
  std::uint64_t sync_sent = 0, pdo_received = 0;  // CAN
  std::uint64_t malformed = 0;                    // frames or replies that broke the protocol
  std::uint64_t error_frames = 0;                 // CAN error frames
  std::uint64_t emcy_count = 0;                   // CAN EMCY messages
  std::uint64_t timeouts = 0;                     // SDO or Modbus request timeouts
  std::uint64_t aborts_or_exceptions = 0;         // SDO aborts / Modbus exception replies
  std::uint64_t reconnects = 0;                   // Modbus reconnects, CAN bus-off recoveries
  std::uint16_t last_emcy_code = 0;
  std::uint8_t last_emcy_register = 0;
  std::array<char, 240> last_error{};  // NUL-terminated; empty when nothing went wrong yet
  // CAN: what made the client latch the fault it holds the drive in (heartbeat lost, the drive's
  // fault, a reboot, a position jump), as last_error said it then; kept until the fault is reset,
  // also when the cause has gone (a heartbeat that came back) and later errors overwrote
  // last_error. Empty while no fault is held.
  std::array<char, 240> fault_cause{};

  std::string_view last_error_text() const noexcept { return last_error.data(); }
  std::string_view fault_cause_text() const noexcept { return fault_cause.data(); }
  void set_last_error(std::string_view text) noexcept {
    const std::size_t n = text.size() < last_error.size() - 1 ? text.size() : last_error.size() - 1;
    std::memcpy(last_error.data(), text.data(), n);
    last_error[n] = '\0';
  }
};

// A single-value mailbox: the newest value wins. One writer, any number of readers. A seqlock
// whose payload lives in relaxed atomic words, so it is race-free under the C++ memory model
// (Boehm, "Can seqlocks get along with programming language memory models?", 2012).
// Real-time safe: no locks, no allocation, no system calls; a reader retries only while a
// store is in progress.
template <class T>
class Mailbox {
  static_assert(std::is_trivially_copyable_v<T>, "Mailbox holds plain data");
  static constexpr std::size_t kWords = (sizeof(T) + 7) / 8;

 public:
  Mailbox() noexcept { store(T{}); }
  explicit Mailbox(const T& initial) noexcept { store(initial); }
  Mailbox(const Mailbox&) = delete;
  Mailbox& operator=(const Mailbox&) = delete;

  // Real-time safe. Only one thread may store.
  void store(const T& value) noexcept {
    std::uint64_t buf[kWords] = {};
    std::memcpy(buf, &value, sizeof(T));
    const std::uint64_t s = seq_.load(std::memory_order_relaxed);
    seq_.store(s + 1, std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_release);
    for (std::size_t i = 0; i < kWords; ++i) words_[i].store(buf[i], std::memory_order_relaxed);
    seq_.store(s + 2, std::memory_order_release);
  }

  // Real-time safe. Any thread.
  T load() const noexcept {
    std::uint64_t buf[kWords];
    for (;;) {
      const std::uint64_t s1 = seq_.load(std::memory_order_acquire);
      if (s1 & 1) continue;
      for (std::size_t i = 0; i < kWords; ++i) buf[i] = words_[i].load(std::memory_order_relaxed);
      std::atomic_thread_fence(std::memory_order_acquire);
      if (seq_.load(std::memory_order_relaxed) == s1) break;
    }
    T out;
    std::memcpy(&out, buf, sizeof(T));
    return out;
  }

  // Real-time safe. Counts stores (the constructor's included).
  std::uint64_t version() const noexcept { return seq_.load(std::memory_order_acquire) / 2; }

 private:
  std::atomic<std::uint64_t> seq_{0};
  std::atomic<std::uint64_t> words_[kWords] = {};
};

}  // namespace hil::drv
