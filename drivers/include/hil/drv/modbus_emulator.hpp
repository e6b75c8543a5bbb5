// Modbus device emulators on a libmodbus server (TCP, or RTU on a serial line / pty), backed by
// the abstract models, laid out by the same YAML register maps the clients use. One thread each.
// A fault API makes them misbehave on purpose.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>

#include "hil/drv/modbus.hpp"
#include "hil/drv/models.hpp"

namespace hil::drv {

// Misbehaviour shared by both emulators (thread-safe).
class ModbusFaults {
 public:
  virtual ~ModbusFaults() = default;
  virtual void set_silent(bool silent) = 0;                              // read requests, answer nothing
  virtual void set_response_delay(std::chrono::microseconds delay) = 0;  // answer late
  // Answer every request with this Modbus exception code (e.g. 2 ILLEGAL DATA ADDRESS,
  // 4 SERVER DEVICE FAILURE, 6 SERVER DEVICE BUSY); 0 answers normally again.
  virtual void set_exception(int code) = 0;
  // The same for the writes only (a device that refuses its target, reads still answered).
  virtual void set_write_exception(int code) = 0;
  // TCP: close every client connection now. RTU: close and reopen the serial line.
  virtual void drop_connections() = 0;
  // TCP: stop listening while set (new connections are refused), listen again when cleared.
  virtual void refuse_connections(bool refuse) = 0;
};

namespace detail {
class ModbusServer;
}

// Registers (by name in the map): holding `control` (bits enable, fault_reset) and
// `target_position`; `status` (bits enabled, fault), `actual_position`, optional
// `actual_velocity` and `fault_code`, refreshed from the model before every reply.
class ModbusDriveEmulator final : public ModbusFaults {
 public:
  // `server`: where to listen (TCP port 0 picks a free port) or the serial device. Throws
  // ModbusError naming the endpoint when it cannot listen/open. `model` must outlive it.
  ModbusDriveEmulator(ModbusLinkConfig server, RegisterMap map, DriveModel& model);
  ~ModbusDriveEmulator() override;
  ModbusDriveEmulator(const ModbusDriveEmulator&) = delete;
  ModbusDriveEmulator& operator=(const ModbusDriveEmulator&) = delete;

  int port() const;  // the TCP port it listens on
  std::uint64_t requests() const;
  // The drive trips by itself with this fault code (status fault bit, fault_code register).
  void raise_fault(std::uint16_t code);
  // A frozen encoder: `actual_position` keeps the value it had (`actual_velocity` reads 0) while
  // the motor moves on.
  void freeze_position(bool frozen);
  // `actual_position` wraps at its register's count range, as an encoder's counter does, instead
  // of saturating there (off by default).
  void wrap_position(bool wrap);

  void set_silent(bool silent) override;
  void set_response_delay(std::chrono::microseconds delay) override;
  void set_exception(int code) override;
  void set_write_exception(int code) override;
  void drop_connections() override;
  void refuse_connections(bool refuse) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Registers: `pressure` (Pa after scale/offset) and optional `status` (bit `fault`).
class ModbusTransducerEmulator final : public ModbusFaults {
 public:
  ModbusTransducerEmulator(ModbusLinkConfig server, RegisterMap map, PressureModel& model);
  ~ModbusTransducerEmulator() override;
  ModbusTransducerEmulator(const ModbusTransducerEmulator&) = delete;
  ModbusTransducerEmulator& operator=(const ModbusTransducerEmulator&) = delete;

  int port() const;
  std::uint64_t requests() const;

  void set_silent(bool silent) override;
  void set_response_delay(std::chrono::microseconds delay) override;
  void set_exception(int code) override;
  void set_write_exception(int code) override;
  void drop_connections() override;
  void refuse_connections(bool refuse) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hil::drv
