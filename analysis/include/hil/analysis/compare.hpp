// `hilbench compare`: replay a measurement through a model, open loop, and say where it fails.
// Streams the file (bounded memory), prints a summary, writes DIR/compare.json and DIR/report.html.
// Offline code: allocates and throws (CsvError for bad files, cfg::Error for bad models,
// std::runtime_error for data the model cannot start from).
#pragma once

#include <filesystem>
#include <functional>
#include <string>

#include <nlohmann/json.hpp>

#include "hil/analysis/cancel.hpp"
#include "hil/analysis/measurement.hpp"
#include "hil/analysis/replay.hpp"
#include "hil/analysis/residuals.hpp"
#include "hil/plant/plant.hpp"
#include "hil/report/run_marks.hpp"

namespace hil::report {
class Document;
}

namespace hil::analysis {

struct ReplayInfo {
  std::filesystem::path data_file;
  bool has_encoder = false, has_reference = false;
  ReplayStart start;
  double wall_s = 0;
};

// progress(fraction 0..1, rows so far) is called about twice a second while streaming.
using Progress = std::function<void(double fraction, std::size_t rows)>;

// Streams `data_file` through `model` (its sensor noise is ignored) and analyses the residual.
// `cancel` set (from another thread): throws Cancelled before the next chunk of rows.
// dialect: the file's CSV dialect (csv_reader.hpp; detected when unset).
ResidualReport compare_file(const plant::Plant& model, const std::filesystem::path& data_file, ReplayInfo* info = nullptr,
                            const Progress& progress = {}, const std::atomic<bool>* cancel = nullptr,
                            const CsvDialect& dialect = {});
// The same on a measurement already in memory (diagnose: before/after).
ResidualReport compare_measurement(const plant::Plant& model, const Measurement& m, bool keep_series = true);

AnalyzerOptions analyzer_options_for(const plant::Plant& model);

// Report sections for one replay (used by compare and, for the final model, by diagnose).
// `group` links the time plots' zoom. `marks`: the run's events (a run folder's events.jsonl
// beside the measurement, run_marks_beside), said in words first ("What happened in the run: ..."),
// then labelled lines on the time plots, faults shaded.
void add_residual_sections(report::Document& doc, const ResidualReport& r, const std::string& group,
                           const std::string& model_label, const report::RunMarks& marks = {});
// The events of the run whose telemetry `data_file` is (events.jsonl in its folder), up to the
// report's end `end_s`; none for a measurement that is not in a run folder.
report::RunMarks run_marks_beside(const std::filesystem::path& data_file, double end_s);
std::string residual_json(const ResidualReport& r, int indent = 2);  // the compare.json body
// compare.json's headline numbers (rows, fit, noise floor, RMSE, largest error, bias, noise), as
// diagnose's before/after blocks and the server's analysis result give them.
nlohmann::json headline_json(const ResidualReport& r);

struct CompareOptions {
  std::filesystem::path model_file, data_file, out_dir;
  CsvDialect dialect;  // the file's CSV dialect (--separator, --decimal, --columns)
  bool progress = true;
  bool quiet = false;
  // When set, called instead of the progress line on stderr (the server's job shows it).
  Progress on_progress = {};
  // Set from another thread to stop: run_compare throws Cancelled before the next chunk of rows
  // or before it writes its outputs, and writes nothing (cancel.hpp).
  const std::atomic<bool>* cancel = nullptr;
};
// The whole command: prints the summary, writes DIR/compare.json and DIR/report.html.
ResidualReport run_compare(const CompareOptions& options);

}  // namespace hil::analysis
