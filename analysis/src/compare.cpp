#include "hil/analysis/compare.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <stdexcept>

#include "hil/line_file.hpp"
#include "hil/output_path.hpp"
#include "hil/progress_line.hpp"
#include "hil/report/report.hpp"
#include "hil/units.hpp"
#include "json_out.hpp"
#include "log_checks.hpp"
#include "text.hpp"

namespace hil::analysis {
namespace {

using Clock = std::chrono::steady_clock;
using units::kPaPerKpa;

// Replays row by row and feeds the analyzer. `next` yields chunks of rows in file order.
template <class NextChunk>
ResidualReport replay_and_analyze(const plant::Plant& model, const MeasurementRows& first, NextChunk&& next, AnalyzerOptions opt,
                                  ReplayInfo* info, const std::filesystem::path& file, RunInputs run) {
  const plant::Plant quiet = noise_free(model);
  const ReplayStart start = estimate_start(first);
  Replayer rep(quiet);
  const double yhat0 = rep.start(start, run.gap_at(first.t_s[0]));
  LogChecks checks(opt.model_lo_pa, opt.model_hi_pa);
  checks.start(start.p0_pa, yhat0, start.motor0_rad);
  if (info) info->start = start;
  ResidualAnalyzer an(opt);
  const bool enc = !first.theta_motor_rad.empty();
  const bool ref = !first.p_ref_pa.empty();
  // With an encoder, a second replay runs the drive model on the command, for the motor channel.
  Replayer drive(quiet);
  if (enc) drive.start(start);
  MotorChannel mc;
  mc.present = enc;
  double sum_d = 0, sum_d2 = 0;
  double cmd_prev = first.theta_cmd_rad[0], t_prev = first.t_s[0];
  bool first_row = true;
  std::size_t row = 0;
  const MeasurementRows* rows = &first;
  MeasurementRows buffer;
  while (rows != nullptr) {
    for (std::size_t k = 0; k < rows->size(); ++k) {
      const double t = rows->t_s[k];
      const double motor = enc ? rows->theta_motor_rad[k] : plant::kNaN;
      const double cmd = rows->theta_cmd_rad[k];
      if (!first_row && !run.gap.empty()) rep.set_gap(run.gap_at(t_prev));
      const double yhat = first_row ? yhat0 : rep.advance_interpolated(t, cmd_prev, cmd, motor);
      // The reader refuses what could make the prediction non-finite; a model that still diverges
      // must stop here, not turn every metric into NaN.
      if (!std::isfinite(yhat)) {
        char b[200];
        std::snprintf(b, sizeof b,
                      ": the model's prediction is not finite at t_s = %.9g (data row %zu): the model "
                      "diverges on this input",
                      t, row);
        throw std::runtime_error(file.string() + b);
      }
      if (enc) {
        if (!first_row) drive.advance_interpolated(t, cmd_prev, cmd, plant::kNaN);
        const double d = units::rad_to_deg(motor - drive.signals().theta_motor_rad);
        sum_d += d;
        sum_d2 += d * d;
        if (std::abs(d) > mc.max_abs_deg) mc.max_abs_deg = std::abs(d), mc.t_at_max_s = t;
        ++mc.samples;
      }
      const bool left_out = run.leave_out(row, t);
      first_row = false;
      ++row;
      cmd_prev = cmd;
      t_prev = t;
      // A left-out row is replayed (the plant's state runs on) but neither checked nor analysed.
      if (left_out) {
        checks.skip(t);
        continue;
      }
      checks.add(t, rows->p_meas_pa[k]);
      an.add({t, rows->p_meas_pa[k], yhat, enc ? motor : cmd, ref ? rows->p_ref_pa[k] : plant::kNaN, rep.burned_kg()});
    }
    rows = next(buffer) ? &buffer : nullptr;
  }
  ResidualReport r = an.finish();
  r.log_warnings = checks.warnings(r.noise_sigma_pa);
  r.run_notes = run.notes(row);
  r.rows_left_out = run.rows_left_out();
  if (mc.samples > 0) {
    mc.bias_deg = sum_d / static_cast<double>(mc.samples);
    mc.rmse_deg = std::sqrt(sum_d2 / static_cast<double>(mc.samples));
    char b[400];
    if (mc.rmse_deg > kMotorChannelTolDeg) {
      std::snprintf(b, sizeof b,
                    "Drive: the encoder differs from the drive model fed with the command by %.3g deg RMS (max %.3g deg "
                    "at %s s): the drive (delay, lag, rate limit) is not what motor_servo says. The pressure replay "
                    "uses the encoder, so this does not enter the error above.",
                    mc.rmse_deg, mc.max_abs_deg, text::instant(mc.t_at_max_s).c_str());
    } else {
      std::snprintf(b, sizeof b, "Drive: the drive model fed with the command follows the encoder (%.3g deg RMS).", mc.rmse_deg);
    }
    r.signature.push_back(b);
  }
  r.motor = mc;
  return r;
}

}  // namespace

AnalyzerOptions analyzer_options_for(const plant::Plant& model) {
  AnalyzerOptions o;
  try {
    const auto [lo, hi] = noise_free(model).pressure_range_pa();
    o.model_lo_pa = lo, o.model_hi_pa = hi;
    if (lo > 0 && hi > lo) o.pressure_lo_pa = 0.5 * lo, o.pressure_hi_pa = 1.5 * hi;
  } catch (const std::exception&) {
    // keep the defaults: the histogram range only shapes a plot; the reach's log check is skipped
  }
  return o;
}

ResidualReport compare_file(const plant::Plant& model, const std::filesystem::path& data_file, ReplayInfo* info,
                            const Progress& progress, const std::atomic<bool>* cancel, const CsvDialect& dialect) {
  const auto t0 = Clock::now();
  MeasurementReader reader(data_file, dialect);
  MeasurementRows first;
  constexpr std::size_t kChunk = 65536;
  if (!reader.next(first, kChunk) || first.size() < kMinRows) {
    MeasurementRows more;
    const bool has_more = first.size() > 0 && reader.next(more, kMinRows);
    if (!has_more) {
      const std::size_t line = first.size() == 0 ? header_line(data_file) + 1 : reader.first_line() + first.size() - 1;
      fail_too_short(data_file, line, first.size());
    }
    first.append(more);
    if (first.size() < kMinRows) fail_too_short(data_file, reader.first_line() + more.size() - 1, first.size());
  }
  if (info) {
    info->data_file = data_file;
    info->has_encoder = reader.has_encoder();
    info->has_reference = reader.has_reference();
  }
  AnalyzerOptions opt = analyzer_options_for(model);
  // Size windows and spectrum segments from the file size and the first chunk's row density.
  const double frac = reader.progress();
  if (frac > 0) {
    opt.expected_rows = static_cast<std::size_t>(static_cast<double>(reader.rows_read()) / frac);
    const double span = first.t_s.back() - first.t_s.front();
    opt.expected_duration_s =
        span / std::max<double>(1.0, static_cast<double>(first.size() - 1)) * static_cast<double>(opt.expected_rows);
  }
  auto last_report = Clock::now();
  auto next = [&](MeasurementRows& rows) {
    throw_if_cancelled(cancel);
    if (progress && Clock::now() - last_report > std::chrono::milliseconds(500)) {
      progress(reader.progress(), reader.rows_read());
      last_report = Clock::now();
    }
    return reader.next(rows, kChunk);
  };
  ResidualReport r = replay_and_analyze(model, first, next, opt, info, data_file, run_inputs_beside(data_file));
  if (progress) progress(1.0, reader.rows_read());
  if (info) info->wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return r;
}

ResidualReport compare_measurement(const plant::Plant& model, const Measurement& m, bool keep_series) {
  AnalyzerOptions opt = analyzer_options_for(model);
  opt.expected_rows = m.rows.size();
  opt.expected_duration_s = m.rows.t_s.back() - m.rows.t_s.front();
  opt.keep_series = keep_series;
  auto none = [](MeasurementRows&) { return false; };
  RunInputs run = m.run;
  run.left_out_counts_reset();
  return replay_and_analyze(model, m.rows, none, opt, nullptr, m.file, std::move(run));
}

// ---------------------------------------------------------------------------------------------
// Report

report::RunMarks run_marks_beside(const std::filesystem::path& data_file, double end_s) {
  return report::marks_from_events(data_file.parent_path() / "events.jsonl", end_s);
}

void add_residual_sections(report::Document& doc, const ResidualReport& r, const std::string& group,
                           const std::string& model_label, const report::RunMarks& marks) {
  using report::Band;
  using report::Figure;
  using report::HLine;
  using report::Series;
  // What the operator did and what failed, in words before the plots that mark it (compare and
  // diagnose say it the same way).
  if (!marks.marks.empty()) doc.paragraph("What happened in the run: " + report::describe_marks(marks.marks) + ".");
  if (!marks.unreadable.empty()) doc.note("events skipped: " + marks.unreadable, true);
  const double kpa = kPaPerKpa;
  std::vector<Band> bands;
  for (std::size_t i = 0; i < r.failing.size(); ++i) {
    bands.push_back({r.failing[i].first, r.failing[i].second, "model fails", ""});
  }
  // Change points of the residual's level, as narrow blue bands (a line the plot can zoom to).
  const double mark_s = 0.15 * r.window_width_s;
  for (const double t : r.change_points_s)
    bands.push_back({t - mark_s, t + mark_s, "change point " + text::num(t, 4) + " s", "rgba(31,119,180,0.55)", "change points"});
  std::vector<Series> pressure = {
      Series{.name = "measured", .x = r.series.measured_mpa.t_s, .y = r.series.measured_mpa.value, .color = "#1f77b4"},
      Series{.name = model_label, .x = r.series.model_mpa.t_s, .y = r.series.model_mpa.value, .color = "#d62728"}};
  if (!r.series.reference_mpa.t_s.empty()) {
    pressure.push_back(Series{.name = "reference",
                              .x = r.series.reference_mpa.t_s,
                              .y = r.series.reference_mpa.value,
                              .color = "#7f7f7f",
                              .style = Series::Style::step,
                              .dashed = true});
  }
  // The run's events (operator injections, faults) on each time plot, in the run report's words.
  const auto marked = [&](Figure f) {
    report::mark_figure(f, marks, true);
    doc.figure(f);
  };
  marked(Figure{.title = "Pressure: measured vs " + model_label + " (shaded: where the model fails)",
                .x_label = "time [s]",
                .y_label = "pressure [MPa]",
                .series = pressure,
                .bands = bands,
                .group = group,
                .height_px = 300});
  const double s3 = 3 * r.noise_sigma_pa / kpa;
  marked(Figure{.title = "Residual: measured - " + model_label,
                .x_label = "time [s]",
                .y_label = "residual [kPa]",
                .series = {Series{
                    .name = "residual", .x = r.series.residual_kpa.t_s, .y = r.series.residual_kpa.value, .color = "#9467bd"}},
                .bands = bands,
                .hlines = {{s3, "+3 sigma noise", true}, {-s3, "-3 sigma noise", true}, {0, "", false}},
                .group = group,
                .height_px = 220});
  marked(
      Figure{.title = "Drive angle (encoder if logged, else command)",
             .x_label = "time [s]",
             .y_label = "angle [deg]",
             .series = {Series{.name = "drive", .x = r.series.drive_deg.t_s, .y = r.series.drive_deg.value, .color = "#2ca02c"}},
             .bands = bands,
             .group = group,
             .height_px = 160});

  // Error by regime.
  report::Bars bars{.title = "Error by regime", .y_label = "error [kPa]", .categories = {}, .groups = {}};
  std::vector<double> rms, bias;
  for (const auto& g : r.regimes) {
    bars.categories.push_back(g.name + " (" + text::num(100 * g.share, 2) + " %)");
    rms.push_back(g.error.rmse_pa / kpa);
    bias.push_back(g.error.bias_pa / kpa);
  }
  bars.groups = {{"RMS", rms}, {"bias", bias}};
  doc.heading("Error by regime; the worst time windows (" + text::num(r.window_width_s, 3) + " s each)", 3);
  doc.columns_begin(2);
  doc.bars(bars);
  {
    std::vector<std::vector<std::string>> rows;
    for (std::size_t i = 0; i < r.worst.size(); ++i) {
      const auto& w = r.windows[r.worst[i]];
      rows.push_back({std::to_string(i + 1), text::instant(w.t0_s), text::instant(w.t1_s), text::num(w.error.rmse_pa / kpa, 3),
                      text::num(w.error.bias_pa / kpa, 3), text::num(w.error.max_abs_pa / kpa, 3), w.regime});
    }
    doc.table({"rank", "from [s]", "to [s]", "RMS [kPa]", "bias [kPa]", "max [kPa]", "motion"}, rows);
  }
  doc.columns_end();

  {
    std::vector<std::vector<std::string>> rows;
    for (const auto& g : r.regimes) {
      rows.push_back({g.name, g.description, text::num(100 * g.share, 3), text::num(g.error.rmse_pa / kpa, 3),
                      text::num(g.error.bias_pa / kpa, 3), text::num(g.error.max_abs_pa / kpa, 3)});
    }
    doc.table({"regime", "definition", "share [%]", "RMS [kPa]", "bias [kPa]", "max [kPa]"}, rows);
  }

  const Diagnostics& d = r.diagnostics;
  doc.heading("Residual diagnostics", 3);
  doc.columns_begin(2);
  doc.figure(Figure{.title = "Autocorrelation of the residual (99 % bounds of white noise)",
                    .x_label = "lag [s]",
                    .y_label = "autocorrelation [-]",
                    .series = {Series{.name = "residual ACF", .x = d.acf_lag_s, .y = d.acf, .color = "#9467bd"}},
                    .hlines = {{d.acf_bound, "+99 %", true}, {-d.acf_bound, "-99 %", true}},
                    .height_px = 220});
  doc.figure(Figure{.title = "Cross-correlation: drive increments -> residual (99 % bounds)",
                    .x_label = "lag [s] (positive: input leads)",
                    .y_label = "cross-correlation [-]",
                    .series = {Series{.name = "input-residual", .x = d.xcf_lag_s, .y = d.xcf, .color = "#8c564b"}},
                    .hlines = {{d.xcf_bound, "+99 %", true}, {-d.xcf_bound, "-99 %", true}},
                    .height_px = 220});
  {
    std::vector<Band> peak_bands;
    for (const auto& pk : d.peaks)
      peak_bands.push_back({pk.hz * 0.97, pk.hz * 1.03, text::num(pk.hz, 3) + " Hz", "rgba(255,160,0,0.35)", "named peaks"});
    doc.figure(Figure{.title = "Residual spectrum (Welch, Hann); peaks marked",
                      .x_label = "frequency [Hz]",
                      .y_label = "PSD [kPa^2/Hz]",
                      .series = {Series{.name = "residual PSD", .x = d.psd_hz, .y = d.psd_kpa2_per_hz, .color = "#17becf"}},
                      .bands = peak_bands,
                      .x_log = true,
                      .y_log = true,
                      .height_px = 220});
  }
  {
    std::vector<double> open_kpa, close_kpa;
    for (double v : d.after_opening_mean_pa) open_kpa.push_back(v / kpa);
    for (double v : d.after_closing_mean_pa) close_kpa.push_back(v / kpa);
    doc.figure(Figure{.title = "Mean residual after motion reversals (" + std::to_string(r.reversals) + " reversals)",
                      .x_label = "time since reversal [s]",
                      .y_label = "mean residual [kPa]",
                      .series = {Series{.name = "into opening", .x = d.since_reversal_s, .y = open_kpa, .color = "#2ca02c"},
                                 Series{.name = "into closing", .x = d.since_reversal_s, .y = close_kpa, .color = "#d62728"}},
                      .hlines = {{0, "", false}},
                      .height_px = 220});
  }
  auto binned = [&](const Binned& b, const std::string& title, bool against_time = false) {
    std::vector<double> mean, rmsv;
    for (double v : b.mean_pa) mean.push_back(v / kpa);
    for (double v : b.rms_pa) rmsv.push_back(v / kpa);
    Figure f{.title = title,
             .x_label = b.quantity + " [" + b.unit + "]",
             .y_label = "residual [kPa]",
             .series = {Series{.name = "mean", .x = b.x, .y = mean, .color = "#1f77b4"},
                        Series{.name = "RMS", .x = b.x, .y = rmsv, .color = "#ff7f0e", .dashed = true}},
             .hlines = {{0, "", false}},
             .height_px = 220};
    if (against_time)
      marked(std::move(f));
    else
      doc.figure(f);
  };
  binned(d.vs_time, "Residual against time (per window)", true);
  binned(d.vs_burned, "Residual against burned propellant (model)");
  binned(d.vs_dpdt, "Residual against dPg/dt (model)");
  binned(d.vs_pressure, "Residual against measured pressure");
  // A drive that never moved leaves no angle bins (an empty plot would be a blank box).
  if (!d.vs_drive_angle.x.empty())
    binned(d.vs_drive_angle, "Residual against drive angle (a ripple with the angle: a gear or coupling error)");
  if (!d.vs_drive_velocity.x.empty())
    binned(d.vs_drive_velocity, "Residual against drive velocity (a misfit near zero: stick-slip)");
  doc.columns_end();
  if (!d.peaks.empty()) {
    std::vector<std::vector<std::string>> rows;
    for (const auto& pk : d.peaks) rows.push_back({text::num(pk.hz, 4), text::num(100 * pk.power_share, 3), pk.name});
    doc.table({"peak [Hz]", "share of residual power [%]", "most likely"}, rows);
  }
}

std::string residual_json(const ResidualReport& r, int indent) { return detail::residual_to_json(r).dump(indent); }

ResidualReport run_compare(const CompareOptions& o) {
  // --out's files: new, or ones a compare wrote; never an input, a device, a FIFO or a link.
  check_output_file("--out", o.out_dir / "report.html", {o.model_file, o.data_file}, "the report", report::kGeneratorTag);
  check_output_file("--out", o.out_dir / "compare.json", {o.model_file, o.data_file}, "compare.json");
  const plant::Plant model = plant::Plant::load(o.model_file);
  Progress progress = o.on_progress;
  std::optional<ProgressLine> line;
  if (!progress && o.progress && !o.quiet) {
    ProgressLine::Options po;
    po.delay_s = 1;  // a short file stays silent
    line.emplace("compare", po);
    progress = [&](double f, std::size_t rows) {
      line->update(f, [&] {
        char detail[48];
        std::snprintf(detail, sizeof detail, "(%zu rows)", rows);
        return std::string(detail);
      });
    };
  }
  ReplayInfo info;
  const ResidualReport r = compare_file(model, o.data_file, &info, progress, o.cancel, o.dialect);
  if (line) line->end();
  throw_if_cancelled(o.cancel);

  std::filesystem::create_directories(o.out_dir);
  auto j = detail::residual_to_json(r);
  j["command"] = "compare";
  j["model_file"] = o.model_file.string();
  j["data_file"] = o.data_file.string();
  j["encoder"] = info.has_encoder;
  j["reference"] = info.has_reference;
  j["start"] = {{"t0_s", info.start.t0_s},
                {"p0_mpa", units::pa_to_mpa(info.start.p0_pa)},
                {"motor0_deg", units::rad_to_deg(info.start.motor0_rad)},
                {"rows_averaged", info.start.rows_averaged}};
  j["wall_s"] = info.wall_s;
  const std::string json_text = j.dump(2) + "\n";

  report::Document doc("Model validation: " + o.model_file.stem().string() + " on " + measurement_label(o.data_file));
  doc.paragraph("Model " + o.model_file.string() + " replayed open loop on " + o.data_file.string() + " (" +
                std::to_string(r.rows) + " rows, " + text::num(r.duration_s, 4) + " s, " +
                (info.has_encoder ? "motor encoder replayed" : "no encoder: the motor model acts on the command") + ").");
  detail::add_summary_table(doc, r);
  for (const auto& w : r.run_notes) doc.note("The run's record: " + w, false);
  for (const auto& w : r.log_warnings) doc.note(w, true);
  doc.note(text::join(r.signature, " "), !(r.fit_pct >= r.noise_floor_fit_pct - 1));
  add_residual_sections(doc, r, "time", "model", run_marks_beside(o.data_file, r.t0_s + r.duration_s));
  // Both or neither: a full disk never leaves this JSON beside an older report.
  const std::string html = doc.html();
  hil::replace_files(std::vector<hil::FileText>{{o.out_dir / "compare.json", {json_text}}, {o.out_dir / "report.html", {html}}});

  if (!o.quiet) {
    std::printf("%s", detail::summary_text(r, o.model_file.filename().string()).c_str());
    std::printf("  wrote %s and %s (%.2f s)\n", (o.out_dir / "compare.json").c_str(), (o.out_dir / "report.html").c_str(),
                info.wall_s);
  }
  return r;
}

}  // namespace hil::analysis
