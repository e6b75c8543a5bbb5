// A CANopen CiA 402 client for one servo drive in cyclic synchronous position mode.
//
// An I/O thread (Boost.Asio) owns the CAN channel: it runs the SDO client (sdo_client.hpp) for the
// setup's object reads and writes, produces SYNC at the loop rate, sends
// RPDO1 (controlword 0x6040, target position 0x607A) before each SYNC, receives TPDO1
// (statusword 0x6041, position actual 0x6064), consumes the drive's heartbeat, decodes EMCY
// and error frames, and runs the CiA 402 state machine. The real-time side only touches
// lock-free mailboxes (read/write/health never block).
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "hil/drv/can.hpp"
#include "hil/drv/canopen.hpp"
#include "hil/drv/io_types.hpp"
#include "hil/drv/parts.hpp"
#include "hil/drv/sdo_client.hpp"  // DriveError, SdoAbortError, SdoClient

namespace hil::cfg {
class Node;
}

namespace hil::drv {

// Encoder counts <-> load-side radians: rad = sign * counts * 2π / (counts_per_rev * gear_ratio).
struct DriveUnits {
  double counts_per_rev = 4096;  // encoder counts per motor revolution
  double gear_ratio = 1.0;       // motor revolutions per load (valve) revolution
  int sign = 1;                  // -1 when the drive counts the other way round
  double rad_per_count() const;
  std::int32_t to_counts(double position_rad) const noexcept;  // rounds, saturates; real-time safe
  double to_rad(std::int32_t counts) const noexcept;           // real-time safe
  static DriveUnits from_yaml(const cfg::Node& units);
};

// What to do when the controller goes bus-off.
enum class BusOffPolicy {
  report,   // latch a fault; resume only when clear_bus_off() is called
  wait,     // latch until the controller reports it restarted (restart-ms / ip link ... restart)
  recover,  // after recover_after, reopen the channel and resume
};

// Throws cfg::Error naming the key unless `n` is a name the kernel takes for a network interface.
void check_can_interface_name(const cfg::Node& n);

struct Cia402Config {
  std::string interface = "vcan0";
  std::uint8_t node_id = 1;
  long bitrate = 1000000;  // informational: a real interface is set up with `ip link`; vcan ignores it
  std::chrono::microseconds sync_period{1000};
  // The shortest SYNC period the bus carries at `bitrate`: RPDO1 + SYNC + TPDO1 with worst-case
  // bit stuffing (285 us at 1 Mbit/s). Shorter is refused by the config and the constructor.
  std::chrono::microseconds min_sync_period() const;
  enum class SyncSource { timer, loop } sync_source = SyncSource::timer;  // loop: write() triggers SYNC
  std::chrono::milliseconds heartbeat_producer{100};                      // written to the drive's 0x1017
  std::chrono::milliseconds heartbeat_timeout{350};
  // Where the drive has no producer heartbeat time 0x1017, node guarding instead (CiA 301 allows
  // either): the I/O thread sends a guarding request (a remote frame on 0x700 + node) every
  // guard_time; the drive's replies are watched as its heartbeat (heartbeat_timeout), and the
  // drive's life guarding (0x100C guard time x 0x100D life time factor) watches the bench in place
  // of the consumer heartbeat 0x1016, with the same reaction (0x6007).
  struct NodeGuarding {
    std::chrono::milliseconds guard_time{100};
    int life_time_factor = 5;
  } node_guarding;
  DriveUnits units;
  std::chrono::milliseconds boot_timeout{5000};
  std::chrono::milliseconds sdo_timeout{200};
  int sdo_retries = 2;
  std::chrono::milliseconds transition_timeout{2000};
  BusOffPolicy bus_off_policy = BusOffPolicy::wait;
  std::chrono::milliseconds bus_off_recover_after{500};
  bool disable_unused_pdos = true;  // mark RPDO2-4 and TPDO2-4 invalid (those the drive has)
  // The bench as a node the drive watches, so that a bench that dies (killed, hung) stops the
  // drive instead of leaving it powered on its last target. From configure() on, the I/O thread
  // produces a heartbeat (CiA 301: 0x700 + node_id, one byte, NMT state operational 0x05) every
  // `producer`; configure() writes the drive's consumer heartbeat time 0x1016 (bits 16-23 node id,
  // 0-15 time in ms) for node_id with `drive_timeout`, and its abort connection option code 0x6007
  // (CiA 402) = `on_loss`, what the drive does when that heartbeat stops.
  struct BenchHeartbeat {
    std::uint8_t node_id = 127;                    // the bench's own node id on this bus (not the drive's)
    std::chrono::milliseconds producer{100};       // the bench's heartbeat period
    std::chrono::milliseconds drive_timeout{500};  // 0x1016 consumer time (> producer, 16 bit)
    std::int16_t on_loss = 3;                      // 0x6007: 1 fault, 2 disable voltage, 3 quick stop
    // configure() fails when the drive has no 0x1016 or no 0x6007 (it could not tell the bench
    // died); false: a configure note instead.
    bool required = true;
  } bench_heartbeat;
  // Written at configure when set (and skipped, with a note in configure_notes(), when the drive
  // lacks the object; all are optional in CiA 402): following error window 0x6065 and timeout
  // 0x6066, max profile velocity 0x607F, quick stop deceleration 0x6085.
  struct Limits {
    double following_error_window_rad = 0;                  // 0: not written
    std::chrono::milliseconds following_error_timeout{-1};  // -1: not written
    double max_profile_velocity_rad_s = 0;                  // 0: not written
    double quick_stop_deceleration_rad_s2 = 0;              // 0: not written
    // The drive's lag behind a target that moves at a constant speed (its position loop),
    // measured: the following error at that speed over the speed (not written anywhere).
    std::chrono::microseconds drive_lag{0};  // 0: unknown
  } limits;
  // The fastest the bench moves the target: set by the rig from its loop.target_shaping and
  // safety.rate_limit (no key of the drive file); 0: unknown. With the drive's lag it says what
  // following error the bench's targets make by themselves (following_window_problem()).
  double target_velocity_rad_s = 0;
  // The longest the loop may go without a write() while it runs the drive (from its first write()
  // after activate() until deactivate()): past it the I/O thread takes the loop for hung, stops
  // the bench's heartbeat (so the drive's consumer trips too) and sends quick stop itself. Set by
  // the rig (the longer of its watchdog time and bench_heartbeat.drive_timeout); 0: not watched.
  std::chrono::milliseconds loop_hang_bound{0};

  // `node` is the drive's mapping (see drivers/configs/cia402_drive.yaml); errors name file:line:key.
  static Cia402Config from_yaml(const cfg::Node& node);
  // A file holding that mapping at its top level or under `cia402_drive:`.
  static Cia402Config load(const std::filesystem::path& file);
};

// The following error the bench's targets make by themselves, target_velocity_rad_s x (the
// drive's lag + one SYNC period: the drive gets each target a period later), against a following
// error window 0x6065 of `window_rad`: the text that refuses the window, with the numbers, when it
// is narrower (the drive would fault on shaping alone); empty when it is wide enough or the
// target velocity is unknown.
std::string following_window_problem(const Cia402Config& config, double window_rad);

// A PositionDrive (parts.hpp), so a rig holds it as one; the rest of its API is its own.
class Cia402Drive final : public PositionDrive {
 public:
  // Opens the channel (SocketCAN on config.interface unless a factory is given) and starts
  // the I/O thread. Throws when the channel cannot be opened.
  explicit Cia402Drive(Cia402Config config, CanTransportFactory transport = {});
  ~Cia402Drive() override;
  Cia402Drive(const Cia402Drive&) = delete;
  Cia402Drive& operator=(const Cia402Drive&) = delete;
  Cia402Drive(Cia402Drive&&) = delete;
  Cia402Drive& operator=(Cia402Drive&&) = delete;

  // Setup (blocking, throw DriveError/SdoAbortError naming node, object and cause).
  // NMT reset communication, wait boot-up, check 0x1000, heartbeat 0x1017, the bench's own
  // heartbeat started and watched by the drive (0x1016, 0x6007), map RPDO1/TPDO1,
  // invalidate the other PDOs the drive has, CSP mode (0x6060 = 8, then 0x6061 polled until it
  // shows 8 or transition_ms passes), interpolation period 0x60C2 and limits where the drive has
  // them, NMT start, wait operational and the first TPDO.
  void configure() override;
  // What configure() skipped because the drive lacks an optional object, one line each.
  std::vector<std::string> configure_notes() const;
  // Shutdown -> switch on -> enable operation (one fault reset first if in fault); the target
  // starts at the actual position. Acknowledges a latched fault (see reset_fault()). When it
  // fails (timeout, cancel) the client goes back to disable voltage.
  void activate() override;
  // The power stage off, whatever the drive's NMT state: disable voltage (switch on disabled) by
  // the cyclic controlword while the PDOs run; where they cannot carry it (pre-operational,
  // stopped, no TPDO) 0x6040 by SDO (quick stop, then disable voltage) with 0x6041 read back by
  // SDO; where SDO fails too, NMT stop. Throws when the state read back is not off (or nothing
  // answered); last_switch_off() says which path did it, how long it took and the state read back.
  void deactivate() override;
  SwitchOff last_switch_off() const override;
  // Quick stop (controlword 0x0002): the drive stops on its quick stop ramp and, with the
  // default quick stop option code, goes to switch on disabled; waits for that.
  void quick_stop();

  // Real-time safe: the newest feedback (sequence counts TPDOs).
  DriveFeedback read(Clock::time_point now, Clock::duration period) noexcept override;
  // Real-time safe: the command for the next SYNC (with sync_source loop, also triggers it).
  void write(Clock::time_point now, Clock::duration period, const DriveCommand& command) noexcept override;
  // Real-time safe.
  DeviceHealth health() const noexcept override;
  // Real-time safe. sync_source loop: each write sends the SYNC the drive answers with a TPDO,
  // so a TPDO since the last write is fresh; timer: the SYNC runs on its own clock (polled).
  FeedbackFreshness freshness() const noexcept override;
  std::string_view missing_reply_text() const noexcept override;  // names a TPDO1 that arrives too short
  // Real-time safe, the thread that writes: a SYNC has carried the newest write's command.
  bool last_command_sent() const noexcept override;
  cia402::State state() const noexcept;  // real-time safe

  // Setup-time services (blocking; never from the I/O thread).
  // The SDO client on this client's channel (sdo_read/sdo_write are it, with the size checked).
  SdoClient& sdo();
  std::uint32_t sdo_read(std::uint16_t index, std::uint8_t sub);
  void sdo_write(std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size);
  void nmt(canopen::NmtCommand command);
  // After a fault (the drive's, or one the client latched: heartbeat lost, left operational,
  // position jump) the client sends quick stop / disable voltage only, until this request (or
  // activate(), or a fault_reset edge in the command): one fault-reset edge at the next SYNC if the
  // drive is in fault. A request with no fault to reset is dropped, not kept for the next one.
  void reset_fault();
  // Any thread: the configure() or activate() in progress throws DriveError "... cancelled"
  // within one poll (2 ms) instead of waiting out its timeouts (up to 600 s each), and so does
  // every later one: a client whose setup was cancelled is being given up (an operator's abort).
  // deactivate() and quick_stop() are not cancelled: they are how a drive is made safe.
  void cancel_setup() noexcept override;
  void clear_bus_off();  // with BusOffPolicy::report: the operator says the bus is fine again

  const Cia402Config& config() const;

 private:
  void configure_bench_watch(bool guarding);
  bool configure_node_guarding();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hil::drv
