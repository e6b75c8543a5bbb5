// What some sub-commands share beyond cli.hpp: the printing of a part's parameters (`effects`,
// `compensators`) and the default output folder of an analysis (`compare`, `diagnose`).
#pragma once

#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "hil/param_spec.hpp"

namespace hil::bench {

// A part's scalar parameters, one line each: key (its unit in its name), range, default or
// "required", meaning. `compensators` and `effects` print them alike.
void print_param_specs(std::span<const ParamSpec> specs);

// compare's and diagnose's folder when --out is not given: out/<kind>-<measurement>-<model>
// (measurement_name: a run's folder name for its telemetry), or that with _2, _3... when the
// folder holds `result_file` of other inputs (another run's result is never overwritten; the same
// inputs analysed again replace their own). Said on stderr when a suffix was needed.
std::filesystem::path default_analysis_dir(const std::string& kind, const std::vector<std::filesystem::path>& data_files,
                                           const std::filesystem::path& model_file, const std::string& result_file);

}  // namespace hil::bench
