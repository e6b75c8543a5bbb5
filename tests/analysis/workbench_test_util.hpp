// Helpers shared by the workbench suites: run the commands as a user would (model file + CSV),
// read back the JSON they wrote.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "hil/analysis/compare.hpp"
#include "hil/analysis/diagnose.hpp"
#include "scenarios.hpp"

namespace hil::test {

inline nlohmann::json read_json(const std::filesystem::path& file) {
  std::ifstream in(file);
  return nlohmann::json::parse(in);
}

// Runs `diagnose` (quiet) on `data` (one file or several of one rig) against `model`; returns
// diagnosis.json.
inline nlohmann::json run_diagnose(const std::filesystem::path& model, const analysis::DataFiles& data,
                                   const std::filesystem::path& out, const std::filesystem::path& write_model = {}) {
  analysis::DiagnoseOptions o;
  o.model_file = model;
  o.data_files = data;
  o.out_dir = out;
  o.write_model = write_model;
  o.quiet = true;
  analysis::run_diagnose(o);
  return read_json(out / "diagnosis.json");
}

inline nlohmann::json run_diagnose(const std::filesystem::path& model, const std::filesystem::path& data,
                                   const std::filesystem::path& out, const std::filesystem::path& write_model = {}) {
  return run_diagnose(model, analysis::DataFiles{data}, out, write_model);
}

inline nlohmann::json run_compare(const std::filesystem::path& model, const std::filesystem::path& data,
                                  const std::filesystem::path& out) {
  analysis::CompareOptions o;
  o.model_file = model;
  o.data_file = data;
  o.out_dir = out;
  o.quiet = true;
  analysis::run_compare(o);
  return read_json(out / "compare.json");
}

// The fitted value of `key` in a candidate entry of diagnosis.json (NaN when absent).
inline const nlohmann::json& param_entry(const nlohmann::json& candidate, const std::string& key) {
  static const nlohmann::json none = nlohmann::json::object();
  for (const auto& p : candidate.at("parameters"))
    if (p.at("key") == key) return p;
  return none;
}

inline double param(const nlohmann::json& candidate, const std::string& key) {
  const auto& p = param_entry(candidate, key);
  return p.contains("value") && !p.at("value").is_null() ? p.at("value").get<double>() : NAN;
}

// The fitted value of `key` of the added effect `effect` in diagnosis.json (NaN when not added).
inline double added_param(const nlohmann::json& d, const std::string& effect, const std::string& key) {
  for (const auto& c : d.at("added"))
    if (c.at("effect") == effect) return param(c, key);
  return NAN;
}

inline std::string brief(const nlohmann::json& d) {
  std::string s = "verdict " + d.value("verdict", std::string("?")) + "; ";
  for (const auto& c : d.at("ranking")) {
    s += c.at("effect").get<std::string>() + " (" + c.at("variant").get<std::string>() + ", fit after " +
         std::to_string(c.at("fit_after_pct").get<double>()) + "); ";
  }
  for (const auto& line : d.at("summary")) s += line.get<std::string>() + " ";
  if (d.contains("paths_followed") && d.at("paths_followed").size() > 1) {
    s += "Paths followed:";
    for (const auto& p : d.at("paths_followed")) {
      std::string effects;
      for (const auto& e : p.at("effects")) {
        if (!effects.empty()) effects += '+';
        effects += e.get<std::string>();
      }
      s += " " + effects + " (fit " + std::to_string(p.at("fit_pct").get<double>()) + ")";
    }
  }
  return s;
}

}  // namespace hil::test
