#include "hil/bench/rt/plant_service.hpp"

#include <cmath>

namespace hil::bench {

PlantService::PlantService(PlantServiceConfig config) : config_(std::move(config)) {
  if (!config_.plant) throw std::invalid_argument("plant service: no plant");
  if (!(config_.period_s > 0)) throw std::invalid_argument("plant service: the period must be > 0");
  state_ = config_.plant->make_state(config_.seed);
  const double gap0 = config_.gap_program ? config_.gap_program->at(0.0) : plant::kNaN;
  config_.plant->settle(state_, config_.p_initial_pa, plant::kNaN, 0.0, gap0);
  PlantSample s;
  s.theta_motor_rad = s.theta_cmd_rad = state_.s.theta_motor_rad;
  s.theta_valve_rad = state_.s.theta_valve_rad;
  s.p_chamber_pa = state_.s.p_chamber_pa;
  s.p_meas_pa = state_.s.p_meas_pa;
  s.gap_rad = state_.s.gap_rad;
  sample_.store(s);
}

PlantService::~PlantService() { stop(); }

drv::DriveModel& PlantService::add_drive() {
  if (running_) throw std::logic_error("plant service: add drives before start()");
  drives_.push_back(std::make_unique<DriveAdapter>(sample_));
  return *drives_.back();
}

drv::DriveModelSample PlantService::DriveAdapter::sample() {
  const PlantSample s = sample_.load();
  return {s.theta_motor_rad, s.velocity_rad_s, false, 0};
}

void PlantService::start() {
  running_ = true;
  thread_ = std::thread([this] { run(); });
  rt_ = make_realtime(thread_, config_.rt_priority, config_.cpu);
}

void PlantService::stop() noexcept {
  running_ = false;  // seen at the top of the plant thread's next step, even if it never waits
  // Taken while the plant thread waits (it holds the mutex otherwise): so it is not between its
  // check of running_ and its wait, and the notification is not lost.
  { std::lock_guard lock(wake_mutex_); }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void PlantService::run() noexcept {
  // Real-time safe from here: the plant steps, mailboxes copy, nothing allocates; the one lock,
  // the wait's, no other thread takes before stop().
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(config_.period_s));
  const plant::Plant& plant = *config_.plant;
  std::vector<std::uint64_t> seen(drives_.size(), 0);  // sized before the loop starts
  Command command{state_.s.theta_motor_rad, false};
  Schedule::Cursor gap_cursor;
  double enabled_at_s = -1;
  PlantSample s = sample_.load();
  auto deadline = Clock::now();
  std::unique_lock wake_lock(wake_mutex_);  // held but while waiting; stop() takes it only to end the run
  while (running_.load(std::memory_order_relaxed)) {
    deadline += period;
    // On CLOCK_MONOTONIC (steady_clock: pthread_cond_clockwait), to the absolute deadline as before.
    if (wake_.wait_until(wake_lock, deadline, [this] { return !running_.load(std::memory_order_relaxed); })) break;
    // The newest command from any drive emulator.
    for (std::size_t i = 0; i < drives_.size(); ++i) {
      const std::uint64_t v = drives_[i]->command_.version();
      if (v != seen[i]) seen[i] = v, command = drives_[i]->command_.load();
    }
    if (command.enabled && enabled_at_s < 0) enabled_at_s = s.t_s;
    // A disabled drive holds where it is; so does one sent a target that is no number (a float
    // register written NaN or inf by any Modbus master), which would poison the plant for good.
    const double cmd = command.enabled && std::isfinite(command.target_rad) ? command.target_rad : s.theta_motor_rad;
    double gap = gap_override_.load(std::memory_order_relaxed);
    if (std::isnan(gap) && config_.gap_program && enabled_at_s >= 0)
      gap = config_.gap_program->at(s.t_s - enabled_at_s, gap_cursor);
    const double before = state_.s.theta_motor_rad;
    plant.step(state_, {cmd, plant::kNaN, gap}, config_.period_s);
    s.t_s = state_.s.t_s;
    s.theta_motor_rad = state_.s.theta_motor_rad;
    s.velocity_rad_s = (state_.s.theta_motor_rad - before) / config_.period_s;
    s.theta_valve_rad = state_.s.theta_valve_rad;
    s.p_chamber_pa = state_.s.p_chamber_pa;
    s.p_meas_pa = state_.s.p_meas_pa;
    s.gap_rad = state_.s.gap_rad;
    s.theta_cmd_rad = cmd;
    s.enabled = command.enabled;
    ++s.steps;
    if (Clock::now() > deadline + period) ++s.late_steps;
    sample_.store(s);
  }
}

}  // namespace hil::bench
