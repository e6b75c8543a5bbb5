#include "hil/analysis/measurement.hpp"

#include <algorithm>
#include <cstdio>

#include "hil/units.hpp"

namespace hil::analysis {
namespace {

CsvRequest measurement_request() {
  return {{"t_s", "theta_cmd_deg", "p_meas_mpa"}, {"theta_motor_deg", "p_ref_mpa"}, "t_s"};
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
}

void MeasurementRows::append(const MeasurementRows& o) {
  auto cat = [](std::vector<double>& a, const std::vector<double>& b) { a.insert(a.end(), b.begin(), b.end()); };
  cat(t_s, o.t_s);
  cat(theta_cmd_rad, o.theta_cmd_rad);
  cat(p_meas_pa, o.p_meas_pa);
  cat(theta_motor_rad, o.theta_motor_rad);
  cat(p_ref_pa, o.p_ref_pa);
}

MeasurementReader::MeasurementReader(const std::filesystem::path& file)
    : file_(file), reader_(file, measurement_request()) {
  has_encoder_ = reader_.header().present[3];
  has_reference_ = reader_.header().present[4];
}

bool MeasurementReader::next(MeasurementRows& rows, std::size_t max_rows) {
  rows.clear();
  if (!reader_.next(chunk_, max_rows)) return false;
  first_line_ = chunk_.first_line;
  if (rows_read_ == 0) first_data_line_ = chunk_.first_line;
  const std::size_t n = chunk_.rows();
  rows_read_ += n;
  rows.t_s = std::move(chunk_.values[0]);
  rows.theta_cmd_rad = std::move(chunk_.values[1]);
  for (double& v : rows.theta_cmd_rad) v = units::deg_to_rad(v);
  rows.p_meas_pa = std::move(chunk_.values[2]);
  for (double& v : rows.p_meas_pa) v = units::mpa_to_pa(v);
  if (has_encoder_) {
    rows.theta_motor_rad = std::move(chunk_.values[3]);
    for (double& v : rows.theta_motor_rad) v = units::deg_to_rad(v);
  }
  if (has_reference_) {
    rows.p_ref_pa = std::move(chunk_.values[4]);
    for (double& v : rows.p_ref_pa) v = units::mpa_to_pa(v);
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

Measurement load_measurement(const std::filesystem::path& file) {
  MeasurementReader reader(file);
  Measurement m;
  m.file = file;
  m.has_encoder = reader.has_encoder();
  m.has_reference = reader.has_reference();
  m.metadata = reader.header().metadata;
  MeasurementRows chunk;
  std::size_t last_line = 0;
  while (reader.next(chunk)) {
    m.rows.append(chunk);
    last_line = reader.first_line() + chunk.size() - 1;  // blank or comment lines in between shift it, rarely
  }
  m.first_data_line = reader.first_data_line();
  if (m.rows.size() < kMinRows) fail_too_short(file, m.rows.size() == 0 ? header_line(file) + 1 : last_line, m.rows.size());
  return m;
}

}  // namespace hil::analysis
