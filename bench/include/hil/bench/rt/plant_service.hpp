// The simulator side of the HIL (`hilbench plant`): the plant model stepped in real time behind
// the device emulators of drivers/ (a CiA 402 drive on CAN, a Modbus drive, a Modbus pressure
// transducer), so the bench's CAN and Modbus rigs can be tested against it as against hardware.
//
// Emulators call the adapters from their own threads; the plant thread steps on absolute
// CLOCK_MONOTONIC deadlines and exchanges data with them through lock-free mailboxes only.
// The drive's encoder reports the motor angle. The gap is physical on a real bench; here it is
// the plant's own, or a campaign's gap programme run on the plant's clock from the moment the
// drive is first enabled, or set by hand.
#pragma once

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "hil/bench/rt/rt_thread.hpp"
#include "hil/bench/rt/schedule.hpp"
#include "hil/drv/io_types.hpp"
#include "hil/drv/models.hpp"
#include "hil/plant/plant.hpp"

namespace hil::bench {

struct PlantServiceConfig {
  std::shared_ptr<const plant::Plant> plant;
  double period_s = 1e-3;
  double p_initial_pa = 1e6;  // the plant starts in steady state here, motor on the opening flank
  std::uint64_t seed = 1;
  std::optional<Schedule> gap_program;  // rad, from the first enable
  int rt_priority = 0;                  // SCHED_FIFO priority of the plant thread (0: normal scheduler)
  int cpu = -1;
};

// What the plant shows, newest first. Plain data for a mailbox.
struct PlantSample {
  double t_s = 0;
  double theta_motor_rad = 0;
  double velocity_rad_s = 0;
  double theta_valve_rad = 0;
  double p_chamber_pa = 0;
  double p_meas_pa = 0;
  double gap_rad = 0;
  double theta_cmd_rad = 0;
  bool enabled = false;
  std::uint64_t steps = 0;
  std::uint64_t late_steps = 0;  // steps taken after their deadline had passed
};

class PlantService {
 public:
  explicit PlantService(PlantServiceConfig config);  // builds and settles the plant
  ~PlantService();                                   // stops the thread
  PlantService(const PlantService&) = delete;
  PlantService& operator=(const PlantService&) = delete;

  // One per emulator that drives the motor (each emulator writes from its own thread).
  drv::DriveModel& add_drive();
  drv::PressureModel& transducer() { return transducer_; }

  void start();  // starts the plant thread; returns what the scheduler granted
  void stop() noexcept;
  const RtSetup& rt() const { return rt_; }

  PlantSample sample() const noexcept { return sample_.load(); }
  // Overrides the gap (rad; NaN: back to the programme or the plant's own). Thread-safe.
  void set_gap(double gap_rad) noexcept { gap_override_.store(gap_rad, std::memory_order_relaxed); }

 private:
  struct Command {
    double target_rad = 0;
    bool enabled = false;
  };
  class DriveAdapter final : public drv::DriveModel {
   public:
    explicit DriveAdapter(const drv::Mailbox<PlantSample>& sample) : sample_(sample) {}
    void command(double target_position_rad, bool enabled) override { command_.store({target_position_rad, enabled}); }
    drv::DriveModelSample sample() override;
    drv::Mailbox<Command> command_;

   private:
    const drv::Mailbox<PlantSample>& sample_;
  };
  class Transducer final : public drv::PressureModel {
   public:
    explicit Transducer(const drv::Mailbox<PlantSample>& sample) : sample_(sample) {}
    double pressure_pa() override { return sample_.load().p_meas_pa; }

   private:
    const drv::Mailbox<PlantSample>& sample_;
  };

  void run() noexcept;  // the plant thread

  PlantServiceConfig config_;
  plant::PlantState state_;
  drv::Mailbox<PlantSample> sample_;
  std::vector<std::unique_ptr<DriveAdapter>> drives_;
  Transducer transducer_{sample_};
  std::atomic<double> gap_override_{plant::kNaN};
  std::atomic<bool> running_{false};
  // The plant thread waits for its next deadline on wake_, so that stop() ends the wait: a sleep
  // to the deadline made a stop (SIGINT/SIGTERM of `hilbench plant`) wait out the period. Only
  // stop() takes the mutex besides the plant thread, so the thread never waits for it mid-run.
  std::mutex wake_mutex_;
  std::condition_variable wake_;
  std::thread thread_;
  RtSetup rt_;
};

}  // namespace hil::bench
