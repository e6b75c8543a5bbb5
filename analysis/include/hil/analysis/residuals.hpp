// Where and how a model fails: the error metrics, the error by regime and by time window, and
// the residual diagnostics of one replay (measured minus predicted pressure), computed in one
// streaming pass with bounded memory (an hour at 1 kHz keeps a few hundred kB of state).
//
// Regimes are classified from the data only (the drive angle and the measured pressure), never
// from the model, so two models compared on the same file see the same regimes.
// Offline code: allocates and throws.
#pragma once

#include <cstddef>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "hil/analysis/noise_model.hpp"

namespace hil::analysis {

// Error statistics of a set of samples; e = measured - model, in Pa.
struct ErrorStats {
  std::size_t samples = 0;
  double rmse_pa = 0, bias_pa = 0, max_abs_pa = 0, t_at_max_s = 0;
};

struct Regime {
  std::string name;         // holding, opening, closing, after_reversal, low_pressure, ...
  std::string description;  // how it is defined, one line
  ErrorStats error;
  double share = 0;  // fraction of all samples in this regime
};

struct TimeWindow {
  double t0_s = 0, t1_s = 0;
  ErrorStats error;
  std::string regime;    // the motion regime most of its samples are in
  double burned_kg = 0;  // model's burned propellant at the window's end
};

// Mean and RMS of the residual in bins of some quantity.
struct Binned {
  std::string quantity, unit;
  std::vector<double> x, mean_pa, rms_pa;
  std::vector<std::size_t> samples;
};

struct SpectrumPeak {
  double hz = 0;
  double power_share = 0;  // of the residual's total power
  std::string name;        // what it most likely is
};

struct Diagnostics {
  double dt_s = 0;  // nominal sample period the correlations and spectrum assume (median dt)
  // Whiteness: normalised autocorrelation of the residual with the 99 % bounds of white noise.
  std::vector<double> acf_lag_s, acf;
  double acf_bound = 0;
  double acf_outside_share = 0;  // of lags 1..whiteness_lags outside the bounds
  bool white = false;
  double tau_int_samples = 1;  // integrated autocorrelation time (Geyer's initial positive sequence)
  double n_eff = 0;            // effective sample size N / tau_int
  // Input-residual cross-correlation (input: drive-angle increments), Bartlett 99 % bound.
  std::vector<double> xcf_lag_s, xcf;
  double xcf_bound = 0, xcf_max_abs = 0, xcf_max_lag_s = 0;
  bool input_correlated = false;
  // Welch spectrum of the residual (Hann, 50 % overlap), kPa^2/Hz.
  std::vector<double> psd_hz, psd_kpa2_per_hz;
  std::vector<SpectrumPeak> peaks;
  double low_frequency_share = 0;  // power below 0.5 Hz (offsets, drifts, slow errors)
  // Event-locked mean residual after motion reversals, separately for reversals into opening
  // and into closing.
  std::vector<double> since_reversal_s, after_opening_mean_pa, after_closing_mean_pa;
  Binned vs_pressure, vs_dpdt, vs_burned, vs_time;
  // Against the drive angle (encoder when logged, else the command), and the strongest ripple
  // periodic in it (src/angle_signature.hpp; period 0: none): what a gear's or coupling's error
  // looks like, which no candidate holds.
  Binned vs_drive_angle;
  double angle_ripple_period_deg = 0, angle_ripple_kpa = 0, angle_ripple_share = 0;
  // Against the drive velocity (asinh bins), and the narrowest band |v| < X that holds the misfit
  // (src/velocity_signature.hpp; 0: none): what a valve that sticks (stick-slip) leaves.
  Binned vs_drive_velocity;
  double velocity_band_deg_s = 0, velocity_band_rms_kpa = 0, velocity_outside_rms_kpa = 0;
  double velocity_band_rows_share = 0, velocity_band_excess_share = 0;
  bool velocity_band_flips = false;  // named for a mean that flips with the direction of motion
  double velocity_band_opening_kpa = 0, velocity_band_closing_kpa = 0;
};

struct TimeSeries {  // min/max-decimated for plots (each bucket keeps its extremes, in time order)
  std::vector<double> t_s, value;
};
struct ReportSeries {
  TimeSeries measured_mpa, model_mpa, residual_kpa, drive_deg, reference_mpa;
};

// With an encoder the pressure replay uses it, so the drive model never acts; this says how well
// the drive model (motor_servo, transport_delay, ...) driven by the command predicts the encoder.
struct MotorChannel {
  bool present = false;  // the file has the encoder
  std::size_t samples = 0;
  double rmse_deg = 0, bias_deg = 0, max_abs_deg = 0, t_at_max_s = 0;  // encoder - model
};
inline constexpr double kMotorChannelTolDeg = 0.05;  // below this RMS the drive model matches

struct ResidualReport {
  std::size_t rows = 0;
  double t0_s = 0, duration_s = 0;
  double fit_pct = 0;              // 100 (1 - |y - yhat| / |y - mean(y)|)
  NoiseModel noise;                // the measurement noise as a process, from the measured pressure alone
  double noise_sigma_pa = 0;       // its total RMS (noise.sigma_pa): the error a perfect model leaves
  std::string noise_method;        // noise.method
  double noise_floor_fit_pct = 0;  // the fit a perfect model would reach with that noise
  double y_spread_pa = 0;          // |y - mean(y)| / sqrt(N)
  ErrorStats error;
  double rss_pa2 = 0;  // sum of squared residuals
  std::vector<Regime> regimes;
  double window_width_s = 0;
  std::vector<TimeWindow> windows;                 // in time order
  std::vector<std::size_t> worst;                  // indices into windows, worst first
  std::vector<std::pair<double, double>> failing;  // merged failing spans [t0, t1]
  // The residual's level against time: the run cut where the windows' RMS changes (change points,
  // file time), each segment with its RMS. See residual_segments().
  struct Segment {
    double t0_s = 0, t1_s = 0, rmse_pa = 0;
    bool at_floor = false;  // RMS within kSegmentFloorRatio of the noise
  };
  std::vector<Segment> segments;
  std::vector<double> change_points_s;
  std::size_t reversals = 0;
  double motion_cycle_hz = 0;     // reversals / (2 * duration): the fundamental of the motion
  double reference_cycle_hz = 0;  // same for p_ref when present
  Diagnostics diagnostics;
  std::vector<std::string> signature;  // plain-language description of the residual
  // What the file itself shows that the replay cannot undo (holes, stale or clipped readings,
  // another unit): filled by the replay (compare.hpp, log_checks.hpp), said before anything else.
  std::vector<std::string> log_warnings;
  // What a recorded run's own record changed (run_inputs.hpp): rows left out, gap inputs. `rows`
  // and every statistic above count the rows kept.
  std::vector<std::string> run_notes;
  std::size_t rows_left_out = 0;
  MotorChannel motor;  // filled by the replay (compare.hpp)
  ReportSeries series;
};

// One row as the analyzer sees it, SI units.
struct ResidualSample {
  double t_s, y_pa, yhat_pa;
  double drive_rad;  // encoder when present, else the command
  double p_ref_pa;   // NaN when absent
  double burned_kg;  // model's burned propellant since the start
};

struct AnalyzerOptions {
  double pressure_lo_pa = 0.2e6, pressure_hi_pa = 5e6;  // histogram range (the model's reach)
  // The model's reach at any valve angle (Plant::pressure_range_pa; NaN: unknown), which the
  // histogram range is set from and the log checks compare the file with (log_checks.hpp).
  double model_lo_pa = std::numeric_limits<double>::quiet_NaN(), model_hi_pa = std::numeric_limits<double>::quiet_NaN();
  double expected_duration_s = 0;  // 0: unknown (windows adapt as data arrives)
  std::size_t expected_rows = 0;   // 0: unknown (sizes the spectrum segments)
  bool keep_series = true;         // decimated series for plots
};

class ResidualAnalyzer {
 public:
  explicit ResidualAnalyzer(const AnalyzerOptions& options);
  ~ResidualAnalyzer();
  ResidualAnalyzer(const ResidualAnalyzer&) = delete;
  ResidualAnalyzer& operator=(const ResidualAnalyzer&) = delete;

  void add(const ResidualSample& s);
  ResidualReport finish();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// "At the noise floor": the RMS error within 10 % of the measurement noise. Used by the residual's
// signature and by diagnose's verdict.
inline constexpr double kNoiseFloorRmsRatio = 1.1;
inline bool at_noise_floor(double rmse_pa, double noise_sigma_pa) { return rmse_pa <= kNoiseFloorRmsRatio * noise_sigma_pa; }

// Fit % of a residual: 100 (1 - sqrt(rss) / |y - mean(y)|).
double fit_percent(double rss_pa2, double y_spread_pa, std::size_t n);

// Change points of the residual's level: binary segmentation of the time windows' mean square,
// a cut kept when the RMS on its two sides differs by at least kChangeRmsRatio and each side
// spans at least two windows (at most kMaxChangePoints cuts). A segment is at the noise floor
// when its RMS is within kSegmentFloorRatio of sigma (short windows scatter more than the whole).
// The signature says where in time the error lives when the segments at the floor make up at
// least a quarter of the run ("confined to 12.2-18 s; before and after it is at the noise floor").
inline constexpr double kChangeRmsRatio = 1.5;
inline constexpr std::size_t kMaxChangePoints = 6;
inline constexpr double kSegmentFloorRatio = 1.3;

// Integrated autocorrelation time (samples) of a residual, by FFT, for the selection criterion.
double integrated_autocorrelation_time(const std::vector<double>& e, std::size_t max_lag = 2000);

}  // namespace hil::analysis
