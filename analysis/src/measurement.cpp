#include "hil/analysis/measurement.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>

#include "hil/telemetry_schema.hpp"
#include "hil/units.hpp"

namespace hil::analysis {
namespace {

using telemetry::Col;

// The measurement format (physics.md section 4, the first columns of the telemetry schema), in the
// schema's order so that values[telemetry::index(c)] is column c.
CsvRequest measurement_request(const CsvDialect& dialect, bool acquisitions) {
  auto n = [](Col c) { return std::string(telemetry::name(c)); };
  return {{n(Col::t_s), n(Col::theta_cmd_deg), n(Col::p_meas_mpa)},
          {n(Col::theta_motor_deg), n(Col::p_ref_mpa)},
          n(Col::t_s),
          dialect,
          acquisitions};
}

}  // namespace

std::size_t header_line(const std::filesystem::path& file) {
  std::FILE* f = std::fopen(file.c_str(), "rb");
  if (f == nullptr) return 1;
  std::size_t line = 1;
  bool blank = true, comment = false, at_start = true;
  for (int c; (c = std::fgetc(f)) != EOF;) {
    if (c == '\n') {
      if (!blank && !comment) break;
      ++line, blank = true, comment = false, at_start = true;
      continue;
    }
    if (c == ' ' || c == '\t' || c == '\r') continue;
    if (at_start && c == '#') comment = true;
    blank = false, at_start = false;
  }
  std::fclose(f);
  return line;
}

void MeasurementRows::clear() {
  for (auto* v : {&t_s, &theta_cmd_rad, &p_meas_pa, &theta_motor_rad, &p_ref_pa}) v->clear();
  restarts.clear();
}

void MeasurementRows::reserve_like(const MeasurementRows& o, std::size_t rows) {
  auto re = [rows](std::vector<double>& a, const std::vector<double>& b) {
    if (!b.empty()) a.reserve(rows);
  };
  re(t_s, o.t_s);
  re(theta_cmd_rad, o.theta_cmd_rad);
  re(p_meas_pa, o.p_meas_pa);
  re(theta_motor_rad, o.theta_motor_rad);
  re(p_ref_pa, o.p_ref_pa);
}

void MeasurementRows::append(const MeasurementRows& o) {
  for (const std::size_t r : o.restarts) restarts.push_back(size() + r);
  auto cat = [](std::vector<double>& a, const std::vector<double>& b) { a.insert(a.end(), b.begin(), b.end()); };
  cat(t_s, o.t_s);
  cat(theta_cmd_rad, o.theta_cmd_rad);
  cat(p_meas_pa, o.p_meas_pa);
  cat(theta_motor_rad, o.theta_motor_rad);
  cat(p_ref_pa, o.p_ref_pa);
}

MeasurementReader::MeasurementReader(const std::filesystem::path& file, const CsvDialect& dialect, bool acquisitions)
    : file_(file), reader_(file, measurement_request(dialect, acquisitions), telemetry::kTopic) {
  has_encoder_ = reader_.header().present[3];
  has_reference_ = reader_.header().present[4];
}

void MeasurementReader::fail_at(std::size_t line, std::string_view column, const std::string& what) const {
  throw CsvError(reader_.where(line, column) + ": " + what);
}

// Per row, in file units (before the conversion to SI), so the messages quote the file.
void MeasurementReader::check_rows(const CsvChunk& c) {
  using L = MeasurementLimits;
  char b[400];
  const auto& t = c.values[telemetry::index(Col::t_s)];
  for (std::size_t r = 0; r < c.rows(); ++r) {
    const std::size_t line = c.lines[r];
    if (std::find(c.restarts.begin(), c.restarts.end(), r) != c.restarts.end()) acquisition_row_ = rows_read_ + r;
    const std::size_t k = rows_read_ + r - acquisition_row_;  // row index in the acquisition
    if (k == 0) t_first_s_ = t_last_s_ = t[r];
    const double dt = t[r] - t_last_s_;
    if (dt > L::kMaxGapS) {
      std::snprintf(b, sizeof b,
                    "a gap of %.6g s in the log (t_s %.9g -> %.9g); the replay crosses gaps of at most %.3g s open "
                    "loop, guessing the inputs: longer than that it is two runs, so cut the file there",
                    dt, t_last_s_, t[r], L::kMaxGapS);
      fail_at(line, telemetry::name(Col::t_s), b);
    }
    const double span = t[r] - t_first_s_;
    if (span > L::kMaxGapS + static_cast<double>(k) * L::kMaxMeanPeriodS) {
      std::snprintf(b, sizeof b,
                    "the log covers %.6g s in its first %zu rows (%.3g s per row); the workbench needs at least one "
                    "row per %.3g s on average (the chamber's ~0.1 s dynamics must be sampled)",
                    span, k + 1, span / static_cast<double>(k + 1), L::kMaxMeanPeriodS);
      fail_at(line, telemetry::name(Col::t_s), b);
    }
    t_last_s_ = t[r];
    const double p = c.values[telemetry::index(Col::p_meas_mpa)][r];
    if (!(p >= L::kMinPressureMpa && p <= L::kMaxPressureMpa)) {
      std::snprintf(b, sizeof b, "%.6g MPa is outside what a chamber-pressure transducer reads here (%.3g to %.3g MPa)", p,
                    L::kMinPressureMpa, L::kMaxPressureMpa);
      fail_at(line, telemetry::name(Col::p_meas_mpa), b);
    }
    const double p_pa = units::mpa_to_pa(p);
    if (k == 0) p_min_pa_ = p_max_pa_ = p_pa;
    p_min_pa_ = std::min(p_min_pa_, p_pa), p_max_pa_ = std::max(p_max_pa_, p_pa);
    for (const Col angle : {Col::theta_cmd_deg, Col::theta_motor_deg}) {
      const auto& values = c.values[telemetry::index(angle)];
      if (values.empty()) continue;
      const double a = values[r];
      if (std::abs(a) > L::kMaxAngleDeg) {
        std::snprintf(b, sizeof b, "%.6g deg is more than a turn from zero (the valve travels 0-30 deg; at most +-%.0f deg)", a,
                      L::kMaxAngleDeg);
        fail_at(line, telemetry::name(angle), b);
      }
    }
    last_data_line_ = line;
  }
}

void MeasurementReader::check_whole_file() const {
  if (rows_read_ < kMinRows) return;  // "too short" is the error that matters then
  if (p_max_pa_ - p_min_pa_ < MeasurementLimits::kMinPressureSpreadPa) {
    char b[300];
    std::snprintf(b, sizeof b,
                  "the reading is %.9g MPa on every row (lines %zu-%zu): a pressure that never moves carries no "
                  "dynamics to compare (a disconnected or saturated channel?)",
                  units::pa_to_mpa(p_min_pa_), first_data_line_, last_data_line_);
    fail_at(first_data_line_, telemetry::name(Col::p_meas_mpa), b);
  }
}

bool MeasurementReader::next(MeasurementRows& rows, std::size_t max_rows) {
  rows.clear();
  if (!reader_.next(chunk_, max_rows)) {
    check_whole_file();
    return false;
  }
  check_rows(chunk_);
  first_line_ = chunk_.first_line;
  if (rows_read_ == 0) first_data_line_ = chunk_.first_line;
  const std::size_t n = chunk_.rows();
  rows_read_ += n;
  rows.restarts = chunk_.restarts;
  rows.t_s = std::move(chunk_.values[telemetry::index(Col::t_s)]);
  rows.theta_cmd_rad = std::move(chunk_.values[telemetry::index(Col::theta_cmd_deg)]);
  for (double& v : rows.theta_cmd_rad) v = telemetry::to_si(Col::theta_cmd_deg, v);
  rows.p_meas_pa = std::move(chunk_.values[telemetry::index(Col::p_meas_mpa)]);
  for (double& v : rows.p_meas_pa) v = telemetry::to_si(Col::p_meas_mpa, v);
  if (has_encoder_) {
    rows.theta_motor_rad = std::move(chunk_.values[telemetry::index(Col::theta_motor_deg)]);
    for (double& v : rows.theta_motor_rad) v = telemetry::to_si(Col::theta_motor_deg, v);
  }
  if (has_reference_) {
    rows.p_ref_pa = std::move(chunk_.values[telemetry::index(Col::p_ref_mpa)]);
    for (double& v : rows.p_ref_pa) v = telemetry::to_si(Col::p_ref_mpa, v);
  }
  return true;
}

double MeasurementReader::progress() const {
  return reader_.file_bytes() > 0 ? std::min(1.0, static_cast<double>(reader_.bytes_read()) / reader_.file_bytes()) : 0.0;
}

void fail_too_short(const std::filesystem::path& file, std::size_t line, std::size_t rows) {
  throw CsvError(file.string() + ":" + std::to_string(line) + ":1: only " + std::to_string(rows) +
                 " data row(s); comparing or fitting needs at least " + std::to_string(kMinRows) +
                 " (the first 50 ms settle the model, the rest carries the dynamics)");
}

namespace {

Measurement read_whole(const std::filesystem::path& file, const CsvDialect& dialect, bool acquisitions) {
  MeasurementReader reader(file, dialect, acquisitions);
  Measurement m;
  m.file = file;
  m.has_encoder = reader.has_encoder();
  m.has_reference = reader.has_reference();
  m.metadata = reader.header().metadata;
  MeasurementRows chunk;
  std::size_t last_line = 0;
  while (reader.next(chunk)) {
    const std::size_t need = m.rows.size() + chunk.size();
    if (need > m.rows.t_s.capacity() && reader.progress() > 0) {
      // Room for the whole file's rows, estimated from the bytes read so far (+1 % while rows
      // remain: later rows may be shorter). Grown chunk by chunk, the columns doubled: a
      // diagnosis held up to twice the rows' memory to its end.
      const double f = reader.progress();
      const double rows = f < 1 ? static_cast<double>(need) / f * 1.01 + 1024 : static_cast<double>(need);
      m.rows.reserve_like(chunk, static_cast<std::size_t>(rows));
    }
    m.rows.append(chunk);
    last_line = reader.first_line() + chunk.size() - 1;  // blank or comment lines in between shift it, rarely
  }
  m.first_data_line = reader.first_data_line();
  if (m.rows.size() < kMinRows) fail_too_short(file, m.rows.size() == 0 ? header_line(file) + 1 : last_line, m.rows.size());
  return m;
}

// The run's record beside a recorded run's telemetry: its left-out rows marked.
void add_run_record(Measurement& m) {
  const auto& file = m.file;
  m.run = run_inputs_beside(file);
  if (!m.run.left_out.empty()) {
    m.left_out.resize(m.rows.size());
    for (std::size_t k = 0; k < m.rows.size(); ++k) m.left_out[k] = m.run.leave_out(k, m.rows.t_s[k]) ? 1 : 0;
    if (m.scored_rows() < kMinRows)
      throw CsvError(file.string() + ": " + std::to_string(m.run.rows_left_out()) + " of " + std::to_string(m.rows.size()) +
                     " rows are inside the run's fault windows (" + m.run.notes(m.rows.size()).front() + "); fewer than " +
                     std::to_string(kMinRows) + " rows are left to compare or fit");
  }
}

// Rows [b, e) of `all` as a Measurement of their own.
Measurement piece(const Measurement& all, std::size_t b, std::size_t e, std::size_t acquisition, std::size_t line) {
  Measurement m;
  m.file = all.file;
  m.has_encoder = all.has_encoder;
  m.has_reference = all.has_reference;
  m.metadata = all.metadata;
  m.acquisition = acquisition;
  m.first_data_line = line;
  auto cut = [&](std::vector<double>& to, const std::vector<double>& from) {
    if (!from.empty()) to.assign(from.begin() + static_cast<std::ptrdiff_t>(b), from.begin() + static_cast<std::ptrdiff_t>(e));
  };
  cut(m.rows.t_s, all.rows.t_s);
  cut(m.rows.theta_cmd_rad, all.rows.theta_cmd_rad);
  cut(m.rows.p_meas_pa, all.rows.p_meas_pa);
  cut(m.rows.theta_motor_rad, all.rows.theta_motor_rad);
  cut(m.rows.p_ref_pa, all.rows.p_ref_pa);
  return m;
}

// The folders that name a run's file, outermost first: a bench run's folder (it holds run.json,
// its name is the run's start, campaign and run), or a sim's <campaign>/<run>/ of telemetry.csv;
// none for any other file.
std::vector<std::string> run_folders(const std::filesystem::path& file) {
  std::error_code ec;
  const auto dir = std::filesystem::weakly_canonical(std::filesystem::absolute(file, ec), ec).parent_path();
  if (std::filesystem::is_regular_file(dir / "run.json", ec)) return {dir.filename().string()};
  if (file.stem() != "telemetry") return {};
  if (dir.parent_path().filename().empty()) return {dir.filename().string()};
  return {dir.parent_path().filename().string(), dir.filename().string()};
}

}  // namespace

std::string measurement_label(const std::filesystem::path& file) {
  std::string label;
  for (const auto& f : run_folders(file)) label += f + "/";
  return label + file.filename().string();
}

std::string measurement_name(const std::filesystem::path& file) {
  const auto folders = run_folders(file);
  std::string name = folders.empty() ? file.stem().string() : folders.front();
  if (folders.size() > 1) name += "_" + folders.back();
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' && c != '-' && c != '+') c = '_';
  return name.empty() ? std::string("data") : name;
}

Measurement load_measurement(const std::filesystem::path& file, const CsvDialect& dialect) {
  Measurement m = read_whole(file, dialect, false);
  add_run_record(m);
  return m;
}

std::vector<Measurement> load_acquisitions(const std::filesystem::path& file, const CsvDialect& dialect) {
  Measurement all = read_whole(file, dialect, true);
  if (all.rows.restarts.empty()) {
    add_run_record(all);
    return {std::move(all)};
  }
  std::vector<std::size_t> cuts = {0};
  cuts.insert(cuts.end(), all.rows.restarts.begin(), all.rows.restarts.end());
  cuts.push_back(all.rows.size());
  // File lines of each acquisition's first row: counted from the header (no blank or comment line
  // between rows is assumed; the error of a too short one names its first row).
  std::vector<Measurement> out;
  for (std::size_t i = 0; i + 1 < cuts.size(); ++i) {
    const std::size_t line = all.first_data_line + cuts[i];
    if (cuts[i + 1] - cuts[i] < kMinRows) fail_too_short(file, line, cuts[i + 1] - cuts[i]);
    out.push_back(piece(all, cuts[i], cuts[i + 1], i + 1, line));
  }
  return out;
}

}  // namespace hil::analysis
