// JSON, console and report pieces shared by compare and diagnose (internal).
#pragma once

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "hil/analysis/residuals.hpp"

namespace hil::report {
class Document;
}

namespace hil::analysis::detail {

nlohmann::json residual_to_json(const ResidualReport& r);
nlohmann::json noise_model_json(const NoiseModel& m);  // compare.json and diagnosis.json: the noise process
void add_summary_table(report::Document& doc, const ResidualReport& r);
std::string summary_text(const ResidualReport& r, const std::string& model_name);

}  // namespace hil::analysis::detail
