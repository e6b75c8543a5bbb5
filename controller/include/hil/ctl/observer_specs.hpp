// The robust observer's settings as a compensator's parameters (config units, ranges, defaults),
// written once for every compensator built on RobustObserver (`robust`, `tracking`): each one's
// kSpecs is joined from these rows and its own, and its values are read back into
// RobustObserverParams here, so a key, a range, a unit conversion or a doc line has one home.
// What each setting does is explained in observer.hpp.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <span>

#include "hil/ctl/observer.hpp"
#include "hil/param_spec.hpp"

namespace hil::ctl {

// The touch-state test and the gap fit: nine rows, in this order, in every compensator that has them.
inline constexpr std::array<ParamSpec, 9> kObserverSpecs{{
    {"intention_sigmas", 0, 1e3, false, false, 8.0, "reversal threshold on the low-passed error, in its noise sigmas"},
    {"filter_time_constant_ms", 1e-3, 1e4, false, false, 15.0, "each of the two low-pass stages of P_eq"},
    {"hold_smoothing", 1, 100, false, false, 4.0, "the hold level's extra low-pass, in filter time constants"},
    {"time_constant_scale", 1e-3, 2, false, false, 0.9, "factor on the nominal chamber time constant in P_eq"},
    {"detect_sigmas", 1e-3, 1e3, false, false, 5.0, "contact threshold, in sigmas of P_eq's noise"},
    {"confirm_samples", 1, 1000, false, false, 5.0, "samples in a row past the contact threshold", true},
    {"fit_lead_ms", 0, 500, false, false, 20.0, "the gap fit's window starts this long before the motor's extreme"},
    {"fit_after_ms", 1, 500, false, false, 40.0, "the gap fit runs this long after contact"},
    {"fit_tries", 1, 1000, false, false, 8.0, "gap fits while the valve has not moved enough", true},
}};

// Rows the compensators share whose default is each one's own design choice (with_fallback).
inline constexpr ParamSpec kIntentionDeadbandSpec{
    "intention_deadband_deg", 0, 10, false, false, 0.05, "retreat of the integral command that is a reversal"};
inline constexpr ParamSpec kGapMaxSpec{"gap_max_deg", 1e-3, 90, false, false, 6.0, "the largest gap a fit may find"};
inline constexpr ParamSpec kContactOverlapSpec{
    "contact_overlap_deg", 0, 1, false, false, 0.02, "the jump aims this far past the flank"};

constexpr ParamSpec with_fallback(ParamSpec spec, double fallback) {
  spec.fallback = fallback;
  return spec;
}

// One table from several, at compile time: a compensator's kSpecs.
template <std::size_t... N>
constexpr auto join_specs(const std::array<ParamSpec, N>&... parts) {
  std::array<ParamSpec, (N + ... + 0)> out{};
  std::size_t i = 0;
  ((std::copy(parts.begin(), parts.end(), out.begin() + i), i += parts.size()), ...);
  return out;
}

// Sets the kObserverSpecs settings of `r` from `v` (their values, in kObserverSpecs' order and
// units: ms to s, counts to int).
inline void apply_observer_specs(RobustObserverParams& r, std::span<const double> v) {
  r.intention_sigmas = v[0];
  r.filter_time_constant_s = v[1] * 1e-3;
  r.hold_smoothing = v[2];
  r.time_constant_scale = v[3];
  r.detect_sigmas = v[4];
  r.confirm_samples = static_cast<int>(v[5]);
  r.fit_lead_s = v[6] * 1e-3;
  r.fit_after_s = v[7] * 1e-3;
  r.fit_tries = static_cast<int>(v[8]);
}

}  // namespace hil::ctl
