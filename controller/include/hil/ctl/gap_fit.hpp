// Measures the backlash from the recent history around a reversal. The observer keeps, per
// control period, the motor angle and the valve angle implied by the equilibrium pressure
// (valve_eq = the nominal map's angle for P_eq, which the filters delay and smooth). For a
// candidate gap sigma, the valve's path follows from the motor's through the play operator,
// starting on the old flank at the motor's extreme; passed through the same two low-pass stages
// it predicts valve_eq up to a constant (map offsets). The gap is the sigma whose prediction fits
// best in least squares: the filters' memory of the gap crossing is modelled, not ignored. A fit
// whose valve hardly moves (less than kMinExcursion residual RMS) is no measurement: a valve that
// did not move cannot tell where contact was.
// Fixed-size storage; fit() is bounded (a coarse grid, then golden section) and real-time safe.
#pragma once

#include <array>
#include <cstdint>

namespace hil::ctl {

class GapFit {
 public:
  static constexpr std::int64_t kCapacity = 1024;  // samples kept (1 s at 1 kHz)
  static constexpr std::int64_t kMaxWindow = 700;  // samples a fit may use: bounds its cost
  static constexpr double kMinExcursion = 4;       // in residual RMS

  // The fit's window, copied out of the ring once so the many cost evaluations run contiguous.
  struct Window {
    std::array<double, kMaxWindow> motor_rad;
    std::array<double, kMaxWindow> valve_eq_rad;
    std::int64_t n = 0;
    std::int64_t extreme = 0;  // index of the motor's extreme within the window (may be < 0)
  };
  struct History {
    std::array<double, kCapacity> motor_rad{};
    std::array<double, kCapacity> valve_eq_rad{};
    std::int64_t count = 0;  // samples pushed so far; sample i lives at i % kCapacity
    Window scratch;          // the fit's working copy (state, so the const model stays shareable)
  };

  struct Result {
    bool ok = false;
    double gap_rad = 0;
    double rms_rad = 0;        // residual of the best fit
    double excursion_rad = 0;  // how far the best fit's valve moved while scored
  };

  // alpha: per-step factor of each of the two low-pass stages.
  GapFit(double alpha, double gap_max_rad) : alpha_(alpha), gap_max_rad_(gap_max_rad) {}

  static void push(History& h, double motor_rad, double valve_eq_rad) noexcept {
    h.motor_rad[slot(h.count)] = motor_rad;
    h.valve_eq_rad[slot(h.count)] = valve_eq_rad;
    ++h.count;
  }
  // Where sample i (count - kCapacity <= i < count) lives in the ring, for a caller that keeps
  // more per sample alongside, or fills valve_eq_rad in after push (before fit reads it).
  static std::size_t slot(std::int64_t i) noexcept { return static_cast<std::size_t>(i % kCapacity); }

  // Fits over samples [extreme - lead, last]: `extreme` is the sample at which the motor turned
  // (last pushing the valve in -dir), `extreme_rad` its angle; dir is the new direction.
  // `skip` samples at the start are simulated but not scored (the filters' start-up).
  Result fit(History& h, std::int64_t extreme, double extreme_rad, int dir, std::int64_t lead, std::int64_t skip) const noexcept;

  // The cost evaluations run four gaps to a register where the CPU has AVX2, else two (SSE2);
  // both give the same bits. Chosen once per process from the CPU; tests and benchmarks switch
  // here to compare (wanted and available). Returns whether the wide lanes are now in use.
  static bool use_wide_lanes(bool wanted) noexcept;

 private:
  double cost(const Window& w, double extreme_rad, int dir, std::int64_t skip, double gap_rad, double* rms = nullptr,
              double* excursion = nullptr) const noexcept;
  template <int K>
  void costs(const Window& w, double extreme_rad, int dir, std::int64_t skip, const double* gap_rad,
             double* cost_out) const noexcept;
  double alpha_;
  double gap_max_rad_;
};

}  // namespace hil::ctl
