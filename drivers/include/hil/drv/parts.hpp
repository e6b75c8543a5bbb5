// The two parts a rig is composed of, whatever bus they sit on: a position drive (the motor with
// its encoder) and a pressure sensor (the chamber's transducer). The bench's device rigs hold
// these interfaces only, so a new drive or sensor client is a new implementation here and no
// change to the rig.
//
// The clients implement them directly (Cia402Drive and ModbusDrive are PositionDrives,
// ModbusTransducer is a PressureSensor) rather than through adapters: their own API already has
// exactly this shape, so an adapter would only forward every call and be one more object per
// device to keep alive next to the client. Their concrete API stays as it was (the probe, SDO
// services, quick stop and the like live only on the concrete class).
//
// Lifecycle (as every rig's): construct (opens nothing, or only the channel) -> configure()
// -> activate() -> read()/write() every period -> deactivate(). Setup calls block and throw
// messages that name the device and the cause; the calls marked "Real-time safe" are noexcept
// and only copy from/to the client's lock-free mailboxes (no allocation, lock or system call
// beyond a client's documented wake-up of its own I/O thread).
#pragma once

#include <string_view>

#include "hil/drv/io_types.hpp"

namespace hil::drv {

// When a drive's newest feedback counts as fresh for the period that reads it.
enum class FeedbackFreshness : std::uint8_t {
  // Each write() makes the drive answer (a CAN drive whose SYNC the loop's write sends): the
  // feedback is fresh when it arrived after the last write, whatever its age.
  reply_to_each_write,
  // The client polls on its own clock: the feedback is fresh while it is younger than the age
  // limit the rig sets (a rig file's max_age_ms).
  polled,
};

class PositionDrive {
 public:
  PositionDrive() = default;
  virtual ~PositionDrive() = default;
  // Parts own I/O threads and sockets: neither copyable nor movable.
  PositionDrive(const PositionDrive&) = delete;
  PositionDrive& operator=(const PositionDrive&) = delete;

  // Setup, blocking, throws naming the device: open the link, check and configure the device.
  virtual void configure() = 0;
  // Setup, blocking, throws: switch the power stage on; the target starts where the motor is.
  virtual void activate() = 0;
  // Setup, blocking, throws: power stage off, the drive keeps its position.
  virtual void deactivate() = 0;
  // Any thread: a configure() or activate() in progress or to come throws instead of waiting, for
  // an operator's abort of a run being set up. A client whose setup waits are short may leave it
  // a no-op.
  virtual void cancel_setup() noexcept {}

  // Real-time safe: the newest feedback from the client's mailbox (position in load-side
  // radians, rx_time when it arrived, sequence counting replies), never waiting for a new one.
  virtual DriveFeedback read(Clock::time_point now, Clock::duration period) noexcept = 0;
  // Real-time safe: hands the target (load-side radians) and enable over to the I/O thread.
  virtual void write(Clock::time_point now, Clock::duration period, const DriveCommand& command) noexcept = 0;
  // Real-time safe: link and device health; last_error names what went wrong last.
  virtual DeviceHealth health() const noexcept = 0;

  // Real-time safe: how the feedback's freshness is judged (fixed once configured).
  virtual FeedbackFreshness freshness() const noexcept = 0;
  // Real-time safe: for reply_to_each_write, what a stale period lacks in the bus's own words
  // ("no TPDO since the last SYNC"), for the rig's fault text. Static storage.
  virtual std::string_view missing_reply_text() const noexcept { return "no reply since the last command"; }
  // Real-time safe: the newest write's command has gone out to the drive (a CAN drive: the SYNC
  // its I/O thread sent carried it). A client that sends only the newest command replaces one
  // written before that unsent; the bench shapes the next target from the last one sent.
  virtual bool last_command_sent() const noexcept { return true; }
  // Setup threads: how the drive was last switched off (io_types.hpp), for the run's record.
  virtual SwitchOff last_switch_off() const { return {}; }
};

class PressureSensor {
 public:
  PressureSensor() = default;
  virtual ~PressureSensor() = default;
  PressureSensor(const PressureSensor&) = delete;
  PressureSensor& operator=(const PressureSensor&) = delete;

  // Setup, blocking, throws naming the device and register: connect, read once, start polling.
  virtual void configure() = 0;

  // Real-time safe: the newest reading (pressure in Pa, rx_time when it arrived: the rig judges
  // freshness by its age; valid false until the first reply; fault from the device or its link).
  virtual PressureReading read(Clock::time_point now, Clock::duration period) noexcept = 0;
  // Real-time safe.
  virtual DeviceHealth health() const noexcept = 0;
};

}  // namespace hil::drv
