// libmodbus clients (TCP or RTU) for a Modbus servo drive and a Modbus pressure transducer.
// Each owns an I/O thread that polls the device, writes commands when they change, and
// reconnects with back-off; the real-time side only touches lock-free mailboxes.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>

#include "hil/drv/io_types.hpp"
#include "hil/drv/modbus_map.hpp"
#include "hil/drv/parts.hpp"

namespace hil::cfg {
class Node;
}

namespace hil::drv {

// Where a device is and how to talk to it. For a server (emulator), host/port are where it
// listens (port 0: any free port) and device is its end of the serial line.
struct ModbusLinkConfig {
  enum class Transport { tcp, rtu } transport = Transport::tcp;
  std::string host = "127.0.0.1";
  int port = 502;
  std::string device;  // RTU: serial device, e.g. /dev/ttyUSB0 or a pty
  int baud = 115200;
  char parity = 'N';  // N, E or O
  int data_bits = 8;
  int stop_bits = 1;
  int unit_id = 1;
  std::chrono::milliseconds response_timeout{100};
  std::chrono::milliseconds poll_period{2};
  std::chrono::milliseconds reconnect_initial{50};  // back-off starts here, doubles per failure...
  std::chrono::milliseconds reconnect_max{2000};    // ...up to this

  // Keys: transport, host, port, device, baud, parity, data_bits, stop_bits, unit_id,
  // response_timeout_ms, poll_period_ms, reconnect: {initial_ms, max_ms}.
  static ModbusLinkConfig from_yaml(const cfg::Node& node);
  std::string describe() const;  // "tcp 127.0.0.1:1502 unit 1" / "rtu /dev/ttyUSB0 115200 8N1 unit 1"
};

// "ILLEGAL DATA ADDRESS" for exception code 2 (Modbus application protocol, section 7).
std::string_view modbus_exception_name(int code);

class ModbusError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ModbusDriveConfig {
  ModbusLinkConfig link;
  RegisterMap map;  // needs: control, target_position (holding); status, actual_position; optional actual_velocity, fault_code
  std::chrono::milliseconds transition_timeout{2000};
  // The longest the loop may go without a write() while it runs the drive (its first write()
  // after activate() until deactivate()): past it the I/O thread takes the loop for hung and
  // writes the control register with enable off itself (a fault until set up again). Set by the
  // rig (the longer of its watchdog time and 500 ms); 0: not watched.
  std::chrono::milliseconds loop_hang_bound{0};
  // `node`: {link: {...}, register_map: <file relative to this one> or {registers: ...}, transition_ms}
  static ModbusDriveConfig from_yaml(const cfg::Node& node);
  static ModbusDriveConfig load(const std::filesystem::path& file);  // top level or `modbus_drive:`
  // Every name the drive (client and emulator) reads from its map; from_yaml refuses others.
  static const MapNames& map_names();
};

struct ModbusTransducerConfig {
  ModbusLinkConfig link;
  RegisterMap map;  // needs: pressure (in Pa after scale/offset); optional status (bit `fault`)
  static ModbusTransducerConfig from_yaml(const cfg::Node& node);
  static ModbusTransducerConfig load(const std::filesystem::path& file);  // top level or `modbus_transducer:`
  // Every name the transducer (client and emulator) reads from its map; from_yaml refuses others.
  static const MapNames& map_names();
};

// The drive's control register: bit `enable` (default 0) switches the power stage on, a rising
// edge of bit `fault_reset` (default 7) clears a fault. Status register: bit `enabled`
// (default 0), bit `fault` (default 3). Bit numbers come from the map's `bits:`.
// A PositionDrive (parts.hpp) whose feedback is polled.
class ModbusDrive final : public PositionDrive {
 public:
  explicit ModbusDrive(ModbusDriveConfig config);  // checks the map; no I/O yet
  ~ModbusDrive() override;
  ModbusDrive(const ModbusDrive&) = delete;
  ModbusDrive& operator=(const ModbusDrive&) = delete;
  ModbusDrive(ModbusDrive&&) = delete;
  ModbusDrive& operator=(ModbusDrive&&) = delete;

  // Connects and polls once (throws ModbusError naming the endpoint and register, e.g.
  // "... reading input registers 0..7 (status, actual_position): ILLEGAL DATA ADDRESS"),
  // then starts the I/O thread.
  void configure() override;
  void activate() override;                    // enable; waits for the status register's enabled bit
  void deactivate() override;                  // disable; waits for it to clear
  SwitchOff last_switch_off() const override;  // path "register": enable off, the status register polled
  // Any thread, for good: activate() stops waiting (throws "activate() cancelled") within a poll
  // (2 ms), configure() refuses to start.
  void cancel_setup() noexcept override;

  DriveFeedback read(Clock::time_point now, Clock::duration period) noexcept override;                       // real-time safe
  void write(Clock::time_point now, Clock::duration period, const DriveCommand& command) noexcept override;  // real-time safe
  DeviceHealth health() const noexcept override;                                                             // real-time safe
  // Real-time safe: the I/O thread polls every poll_period, whatever the loop writes.
  FeedbackFreshness freshness() const noexcept override { return FeedbackFreshness::polled; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// A PressureSensor (parts.hpp).
class ModbusTransducer final : public PressureSensor {
 public:
  explicit ModbusTransducer(ModbusTransducerConfig config);
  ~ModbusTransducer() override;
  ModbusTransducer(const ModbusTransducer&) = delete;
  ModbusTransducer& operator=(const ModbusTransducer&) = delete;
  ModbusTransducer(ModbusTransducer&&) = delete;
  ModbusTransducer& operator=(ModbusTransducer&&) = delete;

  void configure() override;  // connects, reads once (throws naming endpoint and register), starts the thread
  PressureReading read(Clock::time_point now, Clock::duration period) noexcept override;  // real-time safe
  DeviceHealth health() const noexcept override;                                          // real-time safe

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hil::drv
