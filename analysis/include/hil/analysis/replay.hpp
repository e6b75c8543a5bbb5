// Open-loop replay of a measurement through a model: the measured command (and the motor encoder
// when the file has it) drives the plant from a state estimated from the first samples; the
// model's noise-free pressure reading is the prediction.
//
// Time convention (plant_rt): row k holds theta_cmd(k) and p_meas(k); p_meas(k+1) results from
// stepping t(k) -> t(k+1) with theta_cmd(k) held, and the encoder replaces the motor model with
// theta_motor(k+1), the angle at the end of that step. Each step uses its own row's dt, so
// non-uniform sampling is replayed as sampled.
// A log coarser than the bench's period (rows 10 ms apart, say) did not see the commands and
// angles between its rows: holding the row's command over the whole step delays it by half a
// step on average, and the encoder's end angle moves the valve half a step early, which a fit then
// takes for a sensor lag (8.5 ms made up on a 100 Hz log of a plant without one, a 20 ms lag fitted
// as 28.8 ms). Such a step is replayed in substeps of about kInputStepS
// (Replayer::advance_interpolated): the encoder runs on a line between the rows (the motor's
// angle is continuous), the command switches from the previous row's to this row's halfway (it
// may have changed anywhere in the step: halfway is no delay on average; a line smeared the
// compensator's jumps and boosts, 90.8 % fit where holding gave 96.2 %). At the bench's own rate
// it is the held step above.
//
// The model's clock starts at the file's first row (model time = t_s - t_s[0]): the replay starts
// from the model's initial state there (its free volume V(0), say), so time-dependent effects
// (throat_erosion, backlash_change's step_time_s and drift) count from the same origin. For the
// bench's own telemetry t_s[0] = 0 and the two clocks agree.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "hil/analysis/measurement.hpp"
#include "hil/plant/plant.hpp"

namespace hil::analysis {

// Where the replay starts: steady state at the mean pressure of the first settle_s of data, the
// motor at the first encoder angle (or the first command), the valve inside the gap where that
// pressure fits.
struct ReplayStart {
  double t0_s = 0;
  double p0_pa = 0;
  double motor0_rad = 0;
  std::size_t rows_averaged = 0;
};
inline constexpr double kSettleWindowS = 0.05;
ReplayStart estimate_start(const MeasurementRows& first_rows, double settle_s = kSettleWindowS);

// The model as used for prediction: the same effects without the sensor's random noise.
plant::Plant noise_free(const plant::Plant& model);

// Streaming replay, row by row (compare on hour-long files).
class Replayer {
 public:
  explicit Replayer(const plant::Plant& model) : model_(model), state_(model.make_state(1)) {}
  // Steady state at the measured start; when the model cannot reach p0 with the measured motor
  // angle, the valve rests where it comes closest. Returns the prediction for row 0.
  // gap_rad: the gap input in force at the start (NaN: the model's own; run_inputs.hpp).
  double start(const ReplayStart& s, double gap_rad = plant::kNaN);
  // The gap input of the steps from here on (a recorded run's operator changed it; NaN: the model's own).
  void set_gap(double gap_rad) noexcept { gap_rad_ = gap_rad; }
  // Prediction at row time t_s; cmd_held_rad: the command in force since the previous row;
  // motor_rad: the encoder at t_s (NaN: the motor model acts). Real-time safe.
  // A gap in the log (a dropout) is crossed in steps of at most kMaxStepS, the inputs held (the
  // decimated copies of the coarse fits; a file's own rows: advance_interpolated).
  // A step that is not forward in time or longer than MeasurementLimits::kMaxGapS (which
  // load_measurement and MeasurementReader refuse) yields NaN instead of a step count that
  // overflows or a replay that runs for hours.
  double advance(double t_s, double cmd_held_rad, double motor_rad) noexcept {
    const double dt_s = t_s - last_t_s_;
    if (!(dt_s > 0 && dt_s <= MeasurementLimits::kMaxGapS)) return lost_step(t_s, motor_rad);
    const std::size_t n = dt_s > kMaxStepS ? static_cast<std::size_t>(std::ceil(dt_s / kMaxStepS)) : 1;
    return steps(t_s, n, cmd_held_rad, cmd_held_rad, motor_rad, false);
  }
  // The same for rows sampled from inputs that moved between them, in substeps of about
  // kInputStepS: cmd_row_rad is the command logged at t_s, taken from halfway through the step
  // (cmd_held_rad before), and the encoder runs from the previous row's angle to motor_rad. A step
  // under 1.5 kInputStepS is one step, exactly advance()'s.
  double advance_interpolated(double t_s, double cmd_held_rad, double cmd_row_rad, double motor_rad) noexcept {
    const double dt_s = t_s - last_t_s_;
    if (!(dt_s > 0 && dt_s <= MeasurementLimits::kMaxGapS)) return lost_step(t_s, motor_rad);
    const std::size_t n = std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(dt_s / kInputStepS)));
    return steps(t_s, n, cmd_held_rad, cmd_row_rad, motor_rad, true);
  }
  // Longest step the plant is trusted with: the chamber's integrator is accurate well below its ~0.1 s
  // time constant, the servo and sensor lags are discretised exactly. Coarse fits step 12 ms.
  static constexpr double kMaxStepS = 0.02;
  // Substep of an interpolated replay: the bench's control period, which the commands between a
  // coarse log's rows were issued at.
  static constexpr double kInputStepS = 0.001;
  const plant::Signals& signals() const { return state_.s; }
  double burned_kg() const { return burned_kg_; }  // propellant burned since the start (model)

 private:
  const plant::Plant& model_;
  plant::PlantState state_;
  double last_t_s_ = 0;                  // file time of the last row
  double last_motor_rad_ = plant::kNaN;  // the encoder at it (NaN: none)
  double gap_rad_ = plant::kNaN;         // the gap input (NaN: the model's own)
  double burned_kg_ = 0;

  double lost_step(double t_s, double motor_rad) noexcept {
    last_t_s_ = t_s;
    last_motor_rad_ = motor_rad;
    return plant::kNaN;
  }
  // n substeps to t_s: the first half (n/2 rounded up) hold cmd_from, the rest cmd_to; each ends
  // with the motor at motor_rad or, ramp_motor, on the line from the last row's angle to motor_rad
  // (n = 1: cmd_from held, the motor at motor_rad).
  double steps(double t_s, std::size_t n, double cmd_from_rad, double cmd_to_rad, double motor_rad, bool ramp_motor) noexcept {
    const double dt_s = t_s - last_t_s_;
    const double h_s = dt_s / static_cast<double>(n);
    const double inv_n = 1.0 / static_cast<double>(n);  // of the encoder's line
    ramp_motor = ramp_motor && n > 1 && !std::isnan(motor_rad) && !std::isnan(last_motor_rad_);
    for (std::size_t i = 0; i < n; ++i) {
      const double cmd = 2 * i < n ? cmd_from_rad : cmd_to_rad;
      const double motor = ramp_motor && i + 1 < n
                               ? last_motor_rad_ + static_cast<double>(i + 1) * inv_n * (motor_rad - last_motor_rad_)
                               : motor_rad;
      model_.step(state_, {cmd, motor, gap_rad_}, h_s);
      burned_kg_ += state_.s.mdot_gen_kg_s * h_s;
    }
    last_t_s_ = t_s;
    last_motor_rad_ = motor_rad;
    return state_.s.p_meas_pa;
  }
};

// A whole series prepared for repeated replays (fitting): inputs in "held" form so that a
// decimated copy replays with the same code. Several files of one rig (diagnose --data a --data b)
// are held one after the other as segments: each is replayed from its own start, on its own clock
// (model time = t_s - the segment's first t_s), and one parameter vector serves them all, except
// event times (a step of the gap), which are per file: see segment_model.
struct ReplayData {
  std::vector<double> t_s;           // row times
  std::vector<double> cmd_held_rad;  // [k]: command in force over (t[k-1], t[k]]; [segment begin] unused
  std::vector<double> motor_rad;     // [k]: encoder at t[k]; empty: no encoder
  std::vector<double> y_pa;          // measured pressure at t[k]
  // A recorded run's own record (run_inputs.hpp), per row; empty: none. left_out[k]: row k is
  // replayed but not scored (replay() predicts it as measured, so its residual is 0); gap_rad[k]:
  // the gap input over the step to t[k] (NaN: the model's own).
  std::vector<std::uint8_t> left_out;
  std::vector<double> gap_rad;
  std::size_t rows_left_out = 0;
  std::size_t scored_rows() const { return size() - rows_left_out; }
  struct Segment {
    std::size_t begin = 0;  // first row of this file
    ReplayStart start;
    // Where this file starts on the runs' joint clock: the files back to back in the order given,
    // kRunPauseS apart. Event times of a model fitted to several files are on this clock.
    double clock_offset_s = 0;
  };
  static constexpr double kRunPauseS = 1.0;
  std::vector<Segment> segments = {Segment{}};  // at least one; in row order
  std::size_t decimation = 1;                   // rows of the original per row here
  std::size_t size() const { return t_s.size(); }
  // Rows of segment i: [segment_begin(i), segment_end(i)).
  std::size_t segment_begin(std::size_t i) const { return segments[i].begin; }
  std::size_t segment_end(std::size_t i) const { return i + 1 < segments.size() ? segments[i + 1].begin : size(); }
  // Model time segment i covers (its last row's time minus its first's).
  double span_s(std::size_t i) const;
};

// One file, or several of one rig (all with the encoder or all without: the replay treats the
// motor the same way in every segment; std::invalid_argument otherwise).
ReplayData replay_data(const Measurement& m);
ReplayData replay_data(const std::vector<const Measurement*>& files);
// Every m-th row of each segment; the held command is the mean over the rows it replaces
// (preserves the command's integral over each step), the encoder is taken at the end of the step.
ReplayData decimate(const ReplayData& full, std::size_t m);

// Event times: parameters that say when something happened (backlash_change.step_time_s). With
// several files such a value T is on the runs' joint clock, so the event belongs to one file: file
// i sees it at max(0, T - its clock offset), so an event in an earlier file (or between runs) is in
// force from its first row and one in a later file never comes. One file: T as it is.
bool is_event_time(std::string_view effect, std::string_view key);
// `model` as segment i of `data` sees it (its event times moved to the segment's own clock).
plant::Plant segment_model(const plant::Plant& model, const ReplayData& data, std::size_t i);

// Predictions for every row into yhat (size data.size()), each segment from its own start, with
// its segment_model;
// returns false if the model cannot start there (settle out of range) or the prediction is not
// finite.
bool replay(const plant::Plant& model, const ReplayData& data, std::span<double> yhat);

}  // namespace hil::analysis
