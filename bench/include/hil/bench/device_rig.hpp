// The rigs with devices, one class for the three kinds:
//   can     a CiA 402 drive on CAN (the loop's write() triggers SYNC) + a Modbus pressure transducer
//   modbus  a Modbus drive + a Modbus pressure transducer
//   hybrid  a real drive (CAN or Modbus) whose encoder angle drives a simulated backlash, valve and
//           gas generator: the campaign's plant, stepped in lock-step with the loop with
//           plant::PlantInputs::theta_motor_meas_rad. The pressure and the truth come from the
//           simulation, so programmed gap changes work with a real motor.
// The clients (drivers/) own the I/O threads; read/write/health only copy from/to their lock-free
// mailboxes (and, hybrid, step the plant), so they are real-time safe.
#pragma once

#include <memory>

#include "hil/bench/rig.hpp"
#include "hil/bench/rig_config.hpp"
#include "hil/drv/io_types.hpp"
#include "hil/plant/plant.hpp"

namespace hil::bench {

class DeviceRig final : public Rig {
 public:
  // Keeps the configuration; opens nothing until configure().
  explicit DeviceRig(const RigConfig& config, drv::CanTransportFactory can_transport = {});
  ~DeviceRig() override;

  std::string_view kind() const noexcept override { return kind_; }
  bool programmable_gap() const noexcept override { return hybrid_; }
  bool knows_truth() const noexcept override { return hybrid_; }

  // Opens the clients and configures the devices (a CAN drive gets sync_source loop and the
  // run's period as its SYNC period). Hybrid: builds the campaign's plant, settles it at the
  // initial reference and gap, and maps the encoder's angle onto the simulated motor's (an offset
  // kept for the run: commands go out with it added, readings come back with it removed).
  // Throws the clients' errors (they name the device, the object or register, and the cause).
  void configure(const RigSetup& setup) override;
  void activate() override;          // enables the drive
  void deactivate() noexcept override;  // disables it; errors are kept in health()

  // Real-time safe. Stale: the drive's feedback or the pressure is older than its limit (CAN: no
  // TPDO since the last SYNC). Fault: a client reports one (drive fault, heartbeat lost,
  // bus-off, rebooted, Modbus link down, transducer fault).
  RigStatus read(Clock::time_point now, Clock::duration period, RigReading& out) noexcept override;
  RigStatus write(Clock::time_point now, Clock::duration period, const RigCommand& command) noexcept override;
  // Real-time safe; the loop thread (or after it ended): last_error names the device at fault or
  // the stale one, else the newest thing a client reported.
  RigHealth health() const noexcept override;
  // The drive client's newest feedback as it stands (position in the drive's frame, rx_time,
  // sequence), without the rig's freshness bookkeeping: for tests and diagnostics. Real-time safe.
  drv::DriveFeedback drive_feedback() const noexcept;

 private:
  struct DriveClient;
  template <class Client>
  struct DriveClientOf;
  enum class Stale : std::uint8_t { none, drive, transducer };

  RigStatus read_drive(Clock::time_point now, drv::DriveFeedback& fb) noexcept;
  // Before the loop's first write (the reading the run starts from), a Modbus value is fresh if
  // it arrived after activate() began, however old it is by the time the loop starts: a loaded
  // machine may take longer than max_age between enabling the drive and the first period.
  bool first_read(Clock::time_point rx_time) const noexcept { return !first_write_done_ && rx_time >= activated_at_; }

  const RigConfig config_;
  const drv::CanTransportFactory can_transport_;
  const std::string kind_;
  const bool hybrid_;
  std::unique_ptr<DriveClient> drive_;
  std::unique_ptr<drv::ModbusTransducer> transducer_;
  bool active_ = false;
  // Freshness.
  Clock::time_point last_sync_{};  // CAN: when the last write() triggered SYNC
  Clock::time_point activated_at_{};
  bool first_write_done_ = false;
  Stale stale_ = Stale::none;
  double stale_age_ms_ = 0;
  // Hybrid: the simulated valve and chamber.
  std::shared_ptr<const plant::Plant> plant_;
  plant::PlantState state_;
  double period_s_ = 1e-3;
  double offset_rad_ = 0;        // encoder angle - simulated motor angle
  double motor_sim_rad_ = 0;     // the newest encoder angle, in the simulation's frame
  double cmd_sim_rad_ = 0, gap_rad_ = kNaN;
  bool step_pending_ = false;    // a write since the last plant step
  std::uint64_t reads_ = 0, stale_reads_ = 0, fault_reads_ = 0;
  std::array<char, 256> deactivate_error_{};
};

}  // namespace hil::bench
