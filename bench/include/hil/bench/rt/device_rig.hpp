// The rig with devices, composed from the drivers' parts (drivers/include/hil/drv/parts.hpp):
// a position drive, plus either a pressure sensor or the simulated valve and chamber. The kinds
// that use it (bench/src/rt/rigs/) only say which parts:
//   can     a CiA 402 drive on CAN (the loop's write() triggers SYNC) + a Modbus pressure transducer
//   modbus  a Modbus drive + a Modbus pressure transducer
//   hybrid  a real drive (CAN or Modbus) whose encoder angle drives a simulated backlash, valve and
//           gas generator: the campaign's plant, stepped in lock-step with the loop with
//           plant::PlantInputs::theta_motor_meas_rad. The pressure and the truth come from the
//           simulation, so programmed gap changes work with a real motor.
// The parts (drivers/) own the I/O threads; read/write/health only copy from/to their lock-free
// mailboxes (and, with the simulated chamber, step the plant), so they are real-time safe.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>

#include "hil/bench/rt/rig.hpp"
#include "hil/bench/rt/rig_config.hpp"
#include "hil/bench/rt/rig_registry.hpp"
#include "hil/drv/parts.hpp"
#include "hil/plant/plant.hpp"

namespace hil::bench {

class DeviceRig final : public Rig {
 public:
  // The parts are made at configure, not before: a client may open its channel when constructed,
  // and a CAN drive takes the run's period as its SYNC period. Called on the runner's thread.
  using DriveFactory = std::function<std::unique_ptr<drv::PositionDrive>(const RigSetup& setup)>;
  using SensorFactory = std::function<std::unique_ptr<drv::PressureSensor>(const RigSetup& setup)>;

  struct Parts {
    DriveFactory drive;  // required
    // A drive with FeedbackFreshness::polled is stale when its newest feedback is older than this.
    std::chrono::microseconds drive_max_age{0};
    // The chamber's transducer; empty: the pressure comes from the simulated valve and chamber
    // (the campaign's plant stepped with the drive's encoder angle).
    SensorFactory pressure_sensor;
    std::chrono::microseconds sensor_max_age{0};  // a reading older than this is stale
  };

  // Keeps the configuration and the recipe; opens nothing until configure(). `kind` gives the
  // name and capabilities (which must match the parts: a simulated chamber is what makes the gap
  // programmable and the truth known). `config` gives the rig's name, file and I/O priority.
  DeviceRig(const RigConfig& config, const RigKindInfo& kind, Parts parts);
  ~DeviceRig() override;

  std::string_view kind() const noexcept override { return kind_; }
  bool simulated() const noexcept override { return capabilities_.simulated; }
  bool programmable_gap() const noexcept override { return capabilities_.programmable_gap; }
  bool knows_truth() const noexcept override { return capabilities_.knows_truth; }

  // Makes and configures the parts (their I/O threads at the rig's io_priority). With the
  // simulated chamber: builds the campaign's plant, settles it at the initial reference and gap,
  // and maps the encoder's angle onto the simulated motor's (an offset kept for the run: commands
  // go out with it added, readings come back with it removed). Throws the parts' errors (they
  // name the device, the object or register, and the cause).
  void configure(const RigSetup& setup) override;
  void activate() override;               // enables the drive; waits for a fresh reading of every part
  void deactivate() noexcept override;    // disables it; errors are kept in health() and deactivate_failure()
  void cancel_setup() noexcept override;  // passed on to the drive, the one made now or later
  std::string deactivate_failure() const override { return deactivate_error_.data(); }
  drv::SwitchOff switch_off() const override { return drive_ ? drive_->last_switch_off() : drv::SwitchOff{}; }

  // Real-time safe. Stale: the drive's feedback or the pressure is not fresh (a drive answering
  // each write: no reply since the last write; polled parts: older than their limit). Fault: a
  // part reports one (drive fault, heartbeat lost, bus-off, rebooted, link down, transducer fault).
  RigStatus read(Clock::time_point now, Clock::duration period, RigReading& out) noexcept override;
  RigStatus write(Clock::time_point now, Clock::duration period, const RigCommand& command) noexcept override;
  // Real-time safe; the loop thread (or after it ended): last_error names the part at fault or
  // the stale one, else the newest thing a part reported.
  RigHealth health() const noexcept override;
  bool target_sent() const noexcept override;  // the drive's last_command_sent()
  // The drive's newest feedback as it stands (position in the drive's frame, rx_time,
  // sequence), without the rig's freshness bookkeeping: for tests and diagnostics. Real-time safe.
  drv::DriveFeedback drive_feedback() const noexcept;

 private:
  enum class Stale : std::uint8_t { none, drive, transducer };

  RigStatus read_drive(Clock::time_point now, drv::DriveFeedback& fb) noexcept;
  // Before the loop's first write (the reading the run starts from), a polled value is fresh if
  // it arrived after activate() began, however old it is by the time the loop starts: a loaded
  // machine may take longer than max_age between enabling the drive and the first period.
  bool first_read(Clock::time_point rx_time) const noexcept { return !first_write_done_ && rx_time >= activated_at_; }
  bool simulated_chamber() const noexcept { return !parts_.pressure_sensor; }

  const RigConfig config_;
  const std::string kind_;
  const RigCapabilities capabilities_;
  const Parts parts_;
  // Guards drive_ being replaced (configure(), the setup thread) against cancel_setup() (another
  // thread); the loop's calls never take it.
  std::mutex cancel_mutex_;
  // Also read without the lock: by activate()'s wait for fresh readings and between configure()'s parts.
  std::atomic<bool> setup_cancelled_{false};
  std::unique_ptr<drv::PositionDrive> drive_;
  std::unique_ptr<drv::PressureSensor> sensor_;
  drv::FeedbackFreshness drive_freshness_ = drv::FeedbackFreshness::polled;
  bool configured_ = false;  // configure() went through: every part is there
  bool active_ = false;
  // Freshness.
  Clock::time_point last_write_{};  // reply_to_each_write: when the last write() asked for a reply
  Clock::time_point activated_at_{};
  bool first_write_done_ = false;
  Stale stale_ = Stale::none;
  double stale_age_ms_ = 0;
  // The simulated valve and chamber.
  std::shared_ptr<const plant::Plant> plant_;
  plant::PlantState state_;
  double period_s_ = 1e-3;
  double offset_rad_ = 0;     // encoder angle - simulated motor angle
  double motor_sim_rad_ = 0;  // the newest encoder angle, in the simulation's frame
  double cmd_sim_rad_ = 0, gap_rad_ = kNaN;
  bool step_pending_ = false;  // a write since the last plant step
  std::uint64_t reads_ = 0, stale_reads_ = 0, fault_reads_ = 0;
  std::array<char, 256> deactivate_error_{};
  // Feedback no working drive gives, taken as a fault: a position that is not a number, or the
  // drive switching itself off (no fault bit) while every command asked it to stay enabled.
  enum class Implausible : std::uint8_t { none, position_not_finite, disabled };
  Implausible implausible_ = Implausible::none;
  std::uint16_t implausible_status_ = 0;
  bool enable_held_ = false;  // every command since activate() asked for enable
};

// The parts a rig file names (the `devices` block, validated at load), for the kinds' recipes:
// made by the clients' recipes (hil/drv/clients.hpp) with the run's period (a CAN drive takes it
// as its SYNC period, each write sending one SYNC) and `can_transport`. The drive: devices.drive's
// client; throws naming the file when there is none.
DeviceRig::DriveFactory drive_from_file(const RigConfig& config, drv::CanTransportFactory can_transport);
// The transducer: devices.transducer's client; throws naming the file when there is none.
DeviceRig::SensorFactory transducer_from_file(const RigConfig& config);

// The kinds' recipes (a RigKindInfo::make): the file's drive and its pressure transducer (can,
// modbus), or the file's drive with the campaign's valve and chamber simulated behind its encoder
// (hybrid).
std::unique_ptr<Rig> make_drive_and_transducer_rig(const RigKindInfo& kind, const RigConfig& config,
                                                   const drv::CanTransportFactory& can_transport);
std::unique_ptr<Rig> make_drive_and_simulated_chamber_rig(const RigKindInfo& kind, const RigConfig& config,
                                                          const drv::CanTransportFactory& can_transport);

}  // namespace hil::bench
