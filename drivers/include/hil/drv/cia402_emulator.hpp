// A CiA 402 servo drive on a CAN bus, backed by a DriveModel: NMT slave with boot-up and
// heartbeat producer, an SDO server (expedited) for the objects it has (communication objects
// incl. PDO parameters 0x1400-0x1403 / 0x1600-0x1603 / 0x1800-0x1803 / 0x1A00-0x1A03, and
// 0x603F 0x6040 0x6041 0x6060 0x6061 0x6064 0x606C 0x607A 0x60C2), RPDO/TPDO processed on SYNC
// through whatever mapping the master wrote, the CiA 402 state machine, and EMCY.
// One I/O thread. A fault API makes it misbehave on purpose.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "hil/drv/can.hpp"
#include "hil/drv/canopen.hpp"
#include "hil/drv/cia402_drive.hpp"
#include "hil/drv/models.hpp"

namespace hil::drv {

struct Cia402EmulatorConfig {
  std::string interface = "vcan0";
  std::uint8_t node_id = 1;
  DriveUnits units;  // must match the client's to read the same radians

  // How this drive differs from the fullest one; every variant is a legal CiA 301/402 drive.
  int pdos = 4;                                     // RPDOs and TPDOs it has each way, 1..4 (0x1400.., 0x1800..)
  bool interpolation_period = true;                 // has 0x60C2 (optional in CiA 402)
  std::chrono::milliseconds mode_display_delay{0};  // 0x6061 shows a new 0x6060 this much later
  // Has 0x6065 (window, counts; 0xFFFFFFFF = off, the default) and 0x6066 (timeout, ms) and
  // monitors them in CSP: outside the window for longer than the timeout -> EMCY 0x8611
  // (following error; manufacturer bytes: the error in counts, int32 LE) and fault.
  bool following_error = false;
  // Has 0x605A = 2 and 0x6085 (counts/s^2): a quick stop (controlword 0x0002) ramps the speed
  // down at 0x6085, then switch on disabled. Without it: quick stop option 0 (the drive stops
  // at once and goes to switch on disabled).
  bool quick_stop_ramp = false;
  // Has 0x1016 (consumer heartbeat time, 4 entries: bits 16-23 node id, bits 0-15 time in ms,
  // CiA 301) and watches the heartbeats it names: monitoring of a node starts with its first
  // heartbeat after the entry is written; none for the time -> EMCY 0x8130 (heartbeat error) and
  // the abort connection reaction of 0x6007 (CiA 402: 1 fault, 2 disable voltage, 3 quick stop,
  // 0 none), on the drive's own clock (a dead master sends no SYNC either). Monitoring starts
  // again with the node's next heartbeat.
  bool heartbeat_consumer = true;
  bool abort_connection_option = true;  // has 0x6007 (default value 1: fault)
  // Node guarding instead of the heartbeat (CiA 301 allows either): no 0x1017 or 0x1016, but
  // guard time 0x100C (ms) and life time factor 0x100D; answers a guarding request (a remote
  // frame on 0x700 + node) with its NMT state and the toggle bit (bit 7, 0 first after a reset
  // communication), and, once guarded, reacts to no request for guard time x life time factor
  // as to a lost heartbeat (life guarding event: EMCY 0x8130 and 0x6007).
  bool node_guarding = false;
  // PDO2..4 with the maker's own default COB-IDs instead of the predefined connection set's:
  // RPDO k+1 at 0x500 + 0x20 k + node, TPDO k+1 at 0x40000000 (no RTR) | 0x480 + 0x20 k + node.
  bool own_pdo_ids = false;

  // `node`: keys interface, node_id, units (as in Cia402Config), and the variant keys pdos,
  // interpolation_period, mode_display_delay_ms, following_error, quick_stop_ramp,
  // heartbeat_consumer, abort_connection_option, node_guarding, own_pdo_ids.
  static Cia402EmulatorConfig from_yaml(const cfg::Node& node);
  static Cia402EmulatorConfig load(const std::filesystem::path& file);  // top level or `cia402_emulator:`
};

class Cia402DriveEmulator {
 public:
  // Opens the channel (SocketCAN on config.interface unless a factory is given), starts its
  // thread and boots: boot-up message, then pre-operational. `model` must outlive it.
  Cia402DriveEmulator(Cia402EmulatorConfig config, DriveModel& model, CanTransportFactory transport = {});
  ~Cia402DriveEmulator();
  Cia402DriveEmulator(const Cia402DriveEmulator&) = delete;
  Cia402DriveEmulator& operator=(const Cia402DriveEmulator&) = delete;
  Cia402DriveEmulator(Cia402DriveEmulator&&) = delete;
  Cia402DriveEmulator& operator=(Cia402DriveEmulator&&) = delete;

  // Observations, thread-safe.
  canopen::NmtState nmt_state() const;
  cia402::State state() const;
  std::uint64_t syncs_seen() const;
  // Reads an object from the dictionary; nullopt when it does not exist.
  std::optional<std::uint32_t> object(std::uint16_t index, std::uint8_t sub);
  // Where and how fast the motor was when the last quick stop ramp began (quick_stop_ramp
  // variant); nullopt before the first. A test measures the ramp from here, not from a position
  // its own thread read at some earlier moment.
  struct RampStart {
    double position_rad = 0, velocity_rad_s = 0;
  };
  std::optional<RampStart> quick_stop_ramp_start();
  // The heartbeat consumer's events (0x1016), or life guarding's (node 0): how many, and of the last one the node and how long
  // it had been silent when the drive reacted (its last heartbeat to the reaction, on the drive's
  // clock), and the state the reaction left the drive in.
  struct ConsumerEvent {
    std::uint8_t node = 0;
    std::chrono::microseconds silence{0};
    cia402::State state_after = cia402::State::not_ready_to_switch_on;
  };
  std::uint64_t heartbeat_consumer_events() const;
  std::optional<ConsumerEvent> last_consumer_event();

  // Misbehaviour on command, thread-safe.
  void stop_heartbeat(bool stopped);
  // Changes its NMT state by itself, as a drive's 0x1029 error behaviour does on a communication
  // error (pre-operational: SDO still answered, PDOs not processed; stopped: NMT only). The CiA
  // 402 state stays as it was: a drive enabled stays enabled, powered.
  void enter_nmt_state(canopen::NmtState state);
  void set_silent(bool silent);                              // answer nothing at all: no SDO, PDO, heartbeat, NMT reaction
  void set_response_delay(std::chrono::microseconds delay);  // SDO replies and TPDOs go out this late
  // A frozen encoder: 0x6064 keeps the position it had (0x606C reads 0) while the motor moves on.
  void freeze_position(bool frozen);
  // Sends EMCY (code, register, manufacturer bytes) and enters fault; a fault reset clears it
  // (and sends EMCY 0x0000).
  void raise_emcy(std::uint16_t code, std::uint8_t error_register, std::array<std::uint8_t, 5> manufacturer = {});
  // Every SDO access to index:sub is aborted with `abort_code`.
  void fail_sdo(std::uint16_t index, std::uint8_t sub, std::uint32_t abort_code);
  void clear_sdo_failures();
  // Floods the bus with high-priority data frames (default ID 0x001, 8 x 0xFF), `frames_per_ms`
  // every millisecond. Real error frames come from a CAN controller; see emulate_bus_error.
  void flood(bool on, std::uint32_t id = 0x001, int frames_per_ms = 20);
  // Puts an error frame on the bus as a controller driver would report it (bus-off, restarted,
  // error-passive...). On vcan the kernel delivers it to every socket whose CAN_RAW_ERR_FILTER
  // asks for that class, exactly as it delivers a real controller's error frames.
  void emulate_bus_error(EmulatedBusError kind);
  // As if power-cycled: dictionary back to defaults, boot-up message, pre-operational.
  void reboot();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hil::drv
