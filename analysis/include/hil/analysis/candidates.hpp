// Candidate missing effects for `hilbench diagnose`: each is a physical effect of plant_rt (a new
// block, or new values in an existing block) with the parameters a fit may move, their physical
// ranges and starting points. A candidate may have variants (sub-models with fewer free
// parameters, e.g. a constant gap, a drifting gap, a gap that steps once); the information
// criterion picks among them, so a parameter the data does not need is not counted.
//
// Built in: backlash_change, valve_offset, throat_erosion, sensor_lag, transport_delay,
// sensor_bias, motor_dynamics (refits motor_servo), burn_rate (refits gas_generator).
// Each declares how it is found (its fit prior) in its own file, beside its parameter specs
// (hil/plant/fit_prior.hpp, HIL_REGISTER_FIT_PRIOR). User effects: any effect registered with
// HIL_REGISTER_EFFECT that the model does not use, whose parameters all have defaults (the
// defaults meaning "effect absent"), and that is not sensor noise, becomes a candidate by itself:
// with its declared prior when it has one, else all its parameters free, started at the
// defaults, fitted inside its specs() ranges.
#pragma once

#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "hil/analysis/replay.hpp"
#include "hil/plant/plant.hpp"

namespace hil::analysis {

struct FreeParam {
  std::string effect;               // kind of the block holding it
  std::string key;                  // its key in that block (carries the unit)
  double lo = 0, hi = 0;            // fit range, inside the effect's specs
  double scale = 1;                 // typical size: LM scaling and finite-difference step
  std::vector<double> starts = {};  // tried before LM; the best one starts it
  bool grid = false;                // discontinuous (a step time): searched on a grid, not by LM
  // Grid values from the data (grid parameters only), e.g. every 10 ms of the run.
  std::function<std::vector<double>(const ReplayData&)> grid_values = {};
  // A time constant or delay [s]: its finite-difference step is at least one sample period of the
  // data. The replay resolves events (a contact in the gap, a reversal of the command) to whole
  // steps, so the cost has a ripple finer than a sample; a step of 1 % of `scale` (50 us for a
  // lag) measures the ripple's slope, not the trend's, and LM stalls on the lag + delay ridge.
  bool sample_step = false;
  // What the nominal plant makes credible (NaN: anything in [lo, hi]) and why: a fitted value
  // outside it is flagged in the result (FittedParam::implausible), not refused: the file may
  // show a real fault, or the effect may stand in for another (a 4.2 deg gap stepping by 3.15 deg
  // in the first two seconds for a slow drive, issue 37).
  double credible_lo = std::numeric_limits<double>::quiet_NaN(), credible_hi = std::numeric_limits<double>::quiet_NaN();
  std::string credible_why = {};
};

struct Variant {
  std::string name;  // "constant", "drift", "step", "offset and gain", ...
  std::vector<FreeParam> params;
  // Tried only in place of an accepted simpler form of its effect (plant::FitVariant::extends).
  bool extension = false;
};

struct Candidate {
  std::string name;  // effect name as the report and diagnosis.json use it
  std::string description;
  bool command_side = false;  // acts before the motor: invisible when the encoder is replayed
  // The base model with this effect at its neutral values (no change to the prediction).
  std::function<plant::Plant(const plant::Plant&)> attach;
  std::vector<Variant> variants;
};

// Every registered effect with a declared fit prior (hil/plant/fit_prior.hpp: the built-ins and any
// user effect that declares one), their starting values taken from `base`, plus the registry's
// other user effects (see above); the built-ins first. `only`: restrict to these names (empty:
// all). `data` (optional): the file(s), for what the command asks of the drive (FitEvidence).
std::vector<Candidate> candidates_for(const plant::Plant& base, const std::vector<std::string>& only = {},
                                      const ReplayData* data = nullptr);
// What the file's command asks of the drive: the 95th percentile of |d theta_cmd / dt| over 10 ms
// spans where it moves [deg/s] (NaN: too few moving rows).
double command_rate_deg_s(const ReplayData& data);
std::vector<std::string> builtin_candidate_names();

// `plant` with the free parameters set to `values` (same order). Throws std::invalid_argument for
// a value outside the effect's specs.
plant::Plant with_values(const plant::Plant& plant, const std::vector<FreeParam>& params, const std::vector<double>& values);
// The current value of a parameter in `plant` (NaN when absent).
double value_of(const plant::Plant& plant, const std::string& effect, const std::string& key);

}  // namespace hil::analysis
