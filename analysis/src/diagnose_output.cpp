// diagnose's outputs: diagnosis.json, report.html, the fitted model, the console verdict.
#include <unistd.h>

#include <cmath>
#include <cstdio>

#include "hil/analysis/compare.hpp"
#include "hil/analysis/diagnose.hpp"
#include "hil/line_file.hpp"
#include "hil/output_path.hpp"
#include "hil/report/report.hpp"
#include "hil/units.hpp"
#include "json_out.hpp"
#include "text.hpp"

namespace hil::analysis {
namespace {

constexpr double kKpa = units::kPaPerKpa;

nlohmann::json number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json candidate_json(const CandidateResult& c, std::size_t rows) {
  nlohmann::json params = nlohmann::json::array();
  for (const auto& p : c.parameters) {
    params.push_back({{"block", p.effect},
                      {"key", p.key},
                      {"value", number(p.value)},
                      {"uncertainty", number(p.sigma)},
                      {"model_value", number(p.model_value)},
                      {"searched_on_grid", p.grid}});
    if (p.file >= 0) params.back()["file_index"] = p.file;
    if (std::isfinite(p.lo) && std::isfinite(p.hi)) params.back()["fits_within_one_sigma"] = {p.lo, p.hi};
    if (std::isfinite(p.search_lo) && std::isfinite(p.search_hi)) {
      params.back()["search_range"] = {p.search_lo, p.search_hi};
      params.back()["at_search_limit"] = p.at_search_limit();
    }
    if (std::isfinite(p.credible_lo) || std::isfinite(p.credible_hi)) {
      params.back()["credible_range"] = {number(p.credible_lo), number(p.credible_hi)};
      params.back()["implausible"] = p.implausible();
    }
  }
  nlohmann::json j = {{"effect", c.effect},
                      {"variant", c.variant},
                      {"description", c.description},
                      {"parameters", params},
                      {"fit_before_pct", number(c.fit_before_pct)},
                      {"fit_after_pct", number(c.fit_after_pct)},
                      {"excess_explained_pct", number(100 * c.excess_explained)},
                      {"criterion",
                       {{"name", "BIC of the residual prewhitened by the noise model"},
                        {"delta_bic", number(c.delta_bic)},
                        {"free_parameters", c.k},
                        {"samples", rows},
                        {"threshold", -10}}},
                      {"earns_place", c.earns_place},
                      {"refined_on_all_rows", c.refined},
                      {"replays", c.evaluations}};
  if (!c.why_not.empty()) j["why_not"] = c.why_not;
  return j;
}

std::string params_text(const CandidateResult& c) {
  std::string s;
  for (const auto& p : c.parameters) {
    s += (s.empty() ? "" : ", ") + p.key + " = " + text::num(p.value, 4);
    if (std::isfinite(p.sigma) && !p.at_search_limit()) s += " \u00b1 " + text::num(p.sigma, 2);
    s += p.span_text();
    s += p.limit_text();
    s += p.plausibility_text();
    if (p.file >= 0) s += " (file " + std::to_string(p.file + 1) + ")";
  }
  return s;
}

std::string files_text(const DataFiles& data_files) {
  std::string s;
  for (std::size_t i = 0; i < data_files.size(); ++i)
    s += (i == 0 ? "" : i + 1 == data_files.size() ? " and " : ", ") + data_files[i].string();
  return s;
}

}  // namespace

std::string diagnosis_json(const Diagnosis& d, const std::filesystem::path& model_file, const DataFiles& data_files) {
  nlohmann::json j;
  j["command"] = "diagnose";
  j["model_file"] = model_file.string();
  j["data_file"] = data_files.empty() ? "" : data_files.front().string();
  nlohmann::json files = nlohmann::json::array();
  for (std::size_t i = 0; i < d.files.size(); ++i) {
    const FileFit& f = d.files[i];
    files.push_back({{"data_file", i < data_files.size() ? data_files[i].string() : ""},
                     {"rows", f.rows},
                     {"acquisition", f.acquisition},
                     {"first_line", f.first_line},
                     {"time_origin_s", f.time_origin_s},
                     {"noise_sigma_kpa", number(f.before.noise_sigma_pa / kKpa)},
                     {"noise_floor_fit_pct", number(f.before.noise_floor_fit_pct)},
                     {"noise_model", detail::noise_model_json(f.before.noise)},
                     {"fit_before_pct", number(f.before.fit_pct)},
                     {"fit_after_pct", number(f.after.fit_pct)},
                     {"signature", d.explained ? f.after.signature : f.before.signature},
                     {"log_warnings", f.before.log_warnings},
                     {"rows_left_out", f.before.rows_left_out},
                     {"run_notes", f.before.run_notes}});
  }
  j["files"] = files;
  // Which fitted parameters the files share (one rig) and which are per file (an event time: the
  // file it happened in and when, from that file's first row).
  nlohmann::json shared = nlohmann::json::array(), per_file = nlohmann::json::array();
  for (const auto& c : d.added)
    for (const auto& p : c.parameters) {
      if (p.file < 0) {
        shared.push_back(p.effect + "." + p.key);
        continue;
      }
      const auto k = static_cast<std::size_t>(p.file);
      per_file.push_back({{"parameter", p.effect + "." + p.key},
                          {"file_index", p.file},
                          {"data_file", k < data_files.size() ? data_files[k].string() : ""},
                          {"value", number(p.value)},
                          {"file_time_s", number(p.value + (k < d.files.size() ? d.files[k].time_origin_s : 0.0))}});
    }
  j["shared_parameters"] = shared;
  j["per_file_parameters"] = per_file;
  j["rows"] = d.rows;
  j["encoder"] = d.has_encoder;
  j["time_origin_s"] = d.time_origin_s;  // the fitted model's t = 0 is this file time
  j["explained"] = d.explained;
  j["verdict"] = d.verdict;
  j["at_noise_floor"] = d.at_noise_floor;
  j["summary"] = d.summary;
  j["noise_sigma_kpa"] = number(d.noise_sigma_pa / kKpa);
  j["noise_floor_fit_pct"] = number(d.noise_floor_fit_pct);
  j["fit_before_pct"] = number(d.fit_before_pct);
  j["fit_after_pct"] = number(d.fit_after_pct);
  nlohmann::json ranking = nlohmann::json::array();
  if (!d.rounds.empty())
    for (const auto& c : d.rounds.front().ranking) ranking.push_back(candidate_json(c, d.rows));
  j["ranking"] = ranking;
  nlohmann::json added = nlohmann::json::array();
  for (const auto& c : d.added) added.push_back(candidate_json(c, d.rows));
  j["added"] = added;
  nlohmann::json rounds = nlohmann::json::array();
  for (const auto& r : d.rounds) {
    nlohmann::json rk = nlohmann::json::array();
    for (const auto& c : r.ranking) rk.push_back(candidate_json(c, d.rows));
    rounds.push_back({{"fit_before_pct", number(r.fit_before_pct)},
                      {"added", r.added.empty() ? nlohmann::json(nullptr) : nlohmann::json(r.added)},
                      {"note", r.note},
                      {"ranking", rk}});
  }
  j["rounds"] = rounds;
  nlohmann::json paths = nlohmann::json::array();
  for (const auto& p : d.paths)
    paths.push_back(
        {{"effects", p.effects}, {"fit_pct", number(p.fit_pct)}, {"delta_bic_to_chosen", number(p.bic)}, {"chosen", p.chosen}});
  j["paths_followed"] = paths;
  j["revisions"] = d.revisions;
  j["rescue"] = d.rescue;
  j["rivals"] = nlohmann::json::array();
  for (const auto& r : d.rivals)
    j["rivals"].push_back({{"effect", r.effect},
                           {"alternative", r.alternative},
                           {"variant", r.variant},
                           {"delta_bic", number(r.dbic)},
                           {"fit_pct", number(r.fit_pct)}});
  nlohmann::json corr = nlohmann::json::array();
  for (const auto& c : d.correlations) {
    corr.push_back({{"a", c.effect_a + "." + c.key_a},
                    {"b", c.effect_b + "." + c.key_b},
                    {"rho", c.rho},
                    {"indistinguishable", c.indistinguishable}});
  }
  j["parameter_correlations"] = corr;
  nlohmann::json ni = nlohmann::json::array();
  for (const auto& n : d.not_identifiable) ni.push_back({{"effect", n.effect}, {"reason", n.reason}});
  j["not_identifiable"] = ni;
  j["signature"] = d.explained ? d.after.signature : d.before.signature;  // the first file's (files[i] has each)
  j["log_warnings"] = d.before.log_warnings;                              // the first file's, likewise
  nlohmann::json peaks = nlohmann::json::array();
  for (const auto& p : (d.explained ? d.after : d.before).diagnostics.peaks)
    peaks.push_back({{"hz", p.hz}, {"power_share", p.power_share}, {"name", p.name}});
  j["signature_peaks"] = peaks;
  j["before"] = headline_json(d.before);
  j["after"] = headline_json(d.after);
  j["before"]["regimes"] = detail::residual_to_json(d.before)["regimes"];
  j["after"]["regimes"] = detail::residual_to_json(d.after)["regimes"];
  j["method"] = {{"coarse_decimation", d.decimation},
                 {"criterion",
                  "dBIC = N ln(W_c/W_model) + k ln(N), W the residual's sum of squares whitened by the noise model; "
                  "earns its place if dBIC < -10, it "
                  "removes >= 25 % of the excess error power over N sigma^2 and >= 5 % of N sigma^2"},
                 {"replays", d.evaluations},
                 {"wall_s", d.wall_s}};
  return j.dump(2) + "\n";
}

std::string fitted_model_yaml(const Diagnosis& d, const std::filesystem::path& model_file, const DataFiles& data_files) {
  std::string header = "Fitted by hilbench diagnose: " + model_file.string() + " against " + files_text(data_files) + ".\n";
  if (d.added.empty()) {
    header += "No candidate effect earned its place: the model is unchanged.\n";
  } else {
    for (const auto& c : d.added) header += "Added " + c.effect + " (" + c.variant + "): " + params_text(c) + "\n";
  }
  header += "Fit " + text::fixed(d.fit_before_pct, 2) + " % -> " + text::fixed(d.fit_after_pct, 2) + " % (noise floor " +
            text::fixed(d.noise_floor_fit_pct, 2) + " %).";
  return d.fitted->to_yaml(header);
}

namespace {

// One file's before and after: table, overlay, residuals, error by regime. `group`: the plots
// that zoom together (one group per file: the files have their own clocks). `marks`: the run's
// events on the time plots, as compare marks them.
void add_before_after(report::Document& doc, const Diagnosis& d, const FileFit& f, const std::string& title,
                      const std::string& group, const report::RunMarks& marks) {
  using report::Figure;
  using report::Series;
  doc.heading(title);
  {
    auto row = [&](const std::string& name, const ResidualReport& r) {
      return std::vector<std::string>{name,
                                      text::fixed(r.fit_pct, 2),
                                      text::fixed(r.noise_floor_fit_pct, 2),
                                      text::num(r.error.rmse_pa / kKpa, 4),
                                      text::num(r.error.max_abs_pa / kKpa, 4),
                                      text::num(r.error.bias_pa / kKpa, 3)};
    };
    std::string after_name = "after";
    for (const auto& c : d.added) after_name += " + " + c.effect;
    doc.table({"model", "fit [%]", "noise floor [%]", "RMSE [kPa]", "max error [kPa]", "bias [kPa]"},
              {row("before (as given)", f.before), row(d.added.empty() ? "after (unchanged)" : after_name, f.after)});
  }
  const auto& b = f.before.series;
  const auto& a = f.after.series;
  std::vector<Series> overlay = {
      Series{.name = "measured", .x = b.measured_mpa.t_s, .y = b.measured_mpa.value, .color = "#1f77b4"},
      Series{.name = "model before", .x = b.model_mpa.t_s, .y = b.model_mpa.value, .color = "#d62728"}};
  if (!d.added.empty())
    overlay.push_back(
        Series{.name = "model after", .x = a.model_mpa.t_s, .y = a.model_mpa.value, .color = "#2ca02c", .dashed = true});
  std::vector<report::Band> bands;
  for (const auto& span : f.before.failing) bands.push_back({span.first, span.second, "model before fails", ""});
  // Change points of the residual before (where in time something changed), as in compare's report.
  const double mark_s = 0.15 * f.before.window_width_s;
  for (const double t : f.before.change_points_s)
    bands.push_back({t - mark_s, t + mark_s, "change point " + text::num(t, 4) + " s", "rgba(31,119,180,0.55)", "change points"});
  // Where a step found in this file may have happened: the span of times that fit as well.
  for (const auto& c : d.added)
    for (const auto& p : c.parameters) {
      const std::size_t k = p.file < 0 ? 0 : static_cast<std::size_t>(p.file);
      if (!p.located_between() || k >= d.files.size() || &d.files[k] != &f) continue;
      bands.push_back(
          {p.lo + f.time_origin_s, p.hi + f.time_origin_s,
           c.effect + " " + p.key + " = " + text::num(p.value + f.time_origin_s, 5) + ": anywhere in this span fits as well",
           "rgba(44,160,44,0.30)", "where a found step fits as well"});
    }
  Figure pressure{.title = "Pressure: measured, model before and after (shaded: where the model before fails)",
                  .x_label = "time [s]",
                  .y_label = "pressure [MPa]",
                  .series = overlay,
                  .bands = bands,
                  .group = group,
                  .height_px = 300};
  report::mark_figure(pressure, marks, true);
  doc.figure(pressure);
  std::vector<Series> residuals = {
      Series{.name = "residual before", .x = b.residual_kpa.t_s, .y = b.residual_kpa.value, .color = "#d62728"}};
  if (!d.added.empty())
    residuals.push_back(Series{.name = "residual after", .x = a.residual_kpa.t_s, .y = a.residual_kpa.value, .color = "#2ca02c"});
  const double s3 = 3 * f.before.noise_sigma_pa / kKpa;
  Figure residual{.title = "Residual before and after",
                  .x_label = "time [s]",
                  .y_label = "residual [kPa]",
                  .series = residuals,
                  .bands = bands,
                  .hlines = {{s3, "+3 sigma noise", true}, {-s3, "-3 sigma noise", true}},
                  .group = group,
                  .height_px = 240};
  report::mark_figure(residual, marks, true);
  doc.figure(residual);
  {
    report::Bars bars{
        .title = "RMS error by regime, before and after", .y_label = "RMS error [kPa]", .categories = {}, .groups = {}};
    std::vector<double> before, after;
    for (std::size_t i = 0; i < f.before.regimes.size(); ++i) {
      bars.categories.push_back(f.before.regimes[i].name);
      before.push_back(f.before.regimes[i].error.rmse_pa / kKpa);
      after.push_back(i < f.after.regimes.size() ? f.after.regimes[i].error.rmse_pa / kKpa : 0.0);
    }
    bars.groups = {{"before", before}, {"after", after}};
    doc.bars(bars);
  }
}

}  // namespace

std::string diagnosis_report_html(const Diagnosis& d, const std::filesystem::path& model_file, const DataFiles& data_files) {
  const bool several = d.files.size() > 1;
  const std::string first = data_files.empty() ? std::string("data") : measurement_label(data_files.front());
  report::Document doc("Diagnosis: " + first + (several ? " and " + std::to_string(d.files.size() - 1) + " more" : "") +
                       ", model " + model_file.stem().string());
  doc.paragraph("Model " + model_file.string() + " against " + files_text(data_files) + " (" + std::to_string(d.rows) +
                " rows, " + (d.has_encoder ? "motor encoder replayed" : "no encoder") + "). Each candidate effect was " +
                "fitted to the data and ranked by an information criterion; the best one that earns its place is added " +
                "and the search repeats." +
                (several ? " The files are fitted together, as runs of one rig: every parameter is shared by all of them "
                           "(time-dependent ones count from each file's first row)."
                         : ""));
  doc.note(text::join(d.summary, " "), d.verdict != "explained" && d.verdict != "nothing_missing");

  if (several) {
    std::vector<std::vector<std::string>> rows;
    for (std::size_t i = 0; i < d.files.size(); ++i) {
      const FileFit& f = d.files[i];
      rows.push_back({std::to_string(i + 1), i < data_files.size() ? data_files[i].string() : "", std::to_string(f.rows),
                      text::num(f.before.noise_sigma_pa / kKpa, 3), text::fixed(f.before.noise_floor_fit_pct, 2),
                      text::fixed(f.before.fit_pct, 2), text::fixed(f.after.fit_pct, 2)});
    }
    rows.push_back({"all", "", std::to_string(d.rows), text::num(d.noise_sigma_pa / kKpa, 3),
                    text::fixed(d.noise_floor_fit_pct, 2), text::fixed(d.fit_before_pct, 2), text::fixed(d.fit_after_pct, 2)});
    doc.heading("Files", 3);
    doc.table({"file", "path", "rows", "noise [kPa]", "noise floor [%]", "fit before [%]", "fit after [%]"}, rows);
  }
  // Effects that earned their place are shown, also when they only stand in (not explained: the
  // signature below is then the residual's before them, with its plots against angle and velocity).
  // The run's events (a run folder's events.jsonl beside each file) to the end of its data.
  const auto marks_of = [&](std::size_t i) {
    const ResidualReport& r = d.files[i].before;
    return i < data_files.size() ? run_marks_beside(data_files[i], r.t0_s + r.duration_s) : report::RunMarks{};
  };
  if (!d.added.empty()) {
    for (std::size_t i = 0; i < d.files.size(); ++i) {
      const std::string name = i < data_files.size() ? measurement_label(data_files[i]) : std::to_string(i + 1);
      add_before_after(doc, d, d.files[i],
                       several ? "Before and after: file " + std::to_string(i + 1) + ", " + name : "Before and after",
                       several ? "time" + std::to_string(i + 1) : "time", marks_of(i));
    }
  }

  for (std::size_t ri = 0; ri < d.rounds.size(); ++ri) {
    const Round& r = d.rounds[ri];
    doc.heading("Round " + std::to_string(ri + 1) + ": candidates ranked against the model" +
                    (ri == 0 ? " as given" : " with the effects found so far"),
                3);
    if (r.ranking.empty()) {
      doc.paragraph("Fit before this round " + text::fixed(r.fit_before_pct, 2) + " %. Not run: " + r.note + ".");
      continue;
    }
    doc.paragraph("Fit before this round " + text::fixed(r.fit_before_pct, 2) +
                  " %; dBIC on the residual prewhitened by the noise model, every row counted. " +
                  (r.added.empty() ? std::string("Nothing earns its place: the search stops.") : "Added: " + r.added + ".") +
                  (r.note.empty() ? std::string() : " Note: " + r.note + "."));
    std::vector<std::vector<std::string>> rows;
    std::vector<std::string> cats;
    std::vector<double> explained;
    for (std::size_t i = 0; i < r.ranking.size(); ++i) {
      const auto& c = r.ranking[i];
      rows.push_back({std::to_string(i + 1), c.effect, c.variant, params_text(c), text::fixed(c.fit_before_pct, 2),
                      text::fixed(c.fit_after_pct, 2), text::num(c.delta_bic, 4), text::num(100 * c.excess_explained, 3),
                      c.earns_place ? "yes" : "no: " + c.why_not});
      cats.push_back(c.effect);
      explained.push_back(std::isfinite(c.excess_explained) ? 100 * std::max(c.excess_explained, 0.0) : 0.0);
    }
    doc.table({"rank", "effect", "variant", "fitted parameters (\u00b1 1 sigma)", "fit before [%]", "fit after [%]", "dBIC",
               "excess explained [%]", "earns its place"},
              rows);
    if (ri == 0) {
      doc.bars(report::Bars{.title = "Round 1: share of the excess error (above the noise) each candidate explains",
                            .y_label = "excess explained [%]",
                            .categories = cats,
                            .groups = {{"explained", explained}},
                            .height_px = 220});
    }
  }
  if (d.paths.size() > 1) {
    doc.heading("Paths followed", 3);
    doc.paragraph(
        "The best single effect did not reach the noise floor, so the search followed the top first choices "
        "that earn their place, each greedily, and kept the path with the lowest BIC.");
    std::vector<std::vector<std::string>> rows;
    for (const auto& p : d.paths)
      rows.push_back({text::join(p.effects, " + "), text::fixed(p.fit_pct, 2), text::num(p.bic, 4), p.chosen ? "chosen" : ""});
    doc.table({"effects, in the order added", "fit [%]", "BIC - chosen", ""}, rows);
  }
  if (!d.not_identifiable.empty()) {
    std::vector<std::vector<std::string>> rows;
    for (const auto& n : d.not_identifiable) rows.push_back({n.effect, n.reason});
    doc.heading("Not identifiable from this file", 3);
    doc.table({"effect", "why"}, rows);
  }
  for (std::size_t i = 0; i < d.files.size(); ++i) {
    const std::string which = several ? ": file " + std::to_string(i + 1) : "";
    doc.heading((d.explained ? "Where the fitted model still differs" : "Where the model fails (the residual's signature)") +
                which);
    const ResidualReport& last = d.explained ? d.files[i].after : d.files[i].before;
    doc.note(text::join(last.signature, " "), !(last.fit_pct >= last.noise_floor_fit_pct - 1));
    add_residual_sections(doc, last, several ? "time" + std::to_string(i + 1) : "time", d.explained ? "model after" : "model",
                          marks_of(i));
  }
  return doc.html();
}

namespace {

// --write-model and the files of --out: new, or ones a diagnose wrote; never an input, a folder,
// a device, a FIFO or a link. Said before the fit.
void check_model_output(const DiagnoseOptions& o) {
  std::vector<std::filesystem::path> inputs = o.data_files;
  inputs.push_back(o.model_file);
  check_output_file("--out", o.out_dir / "report.html", inputs, "the report", report::kGeneratorTag);
  check_output_file("--out", o.out_dir / "diagnosis.json", inputs, "diagnosis.json");
  if (o.write_model.empty()) return;
  check_output_file("--write-model", o.write_model, inputs, "the fitted model", "Fitted by hilbench diagnose");
}

}  // namespace

Diagnosis run_diagnose(const DiagnoseOptions& o) {
  if (o.data_files.empty()) throw std::invalid_argument("diagnose: no measurement file given");
  check_model_output(o);  // before minutes of fitting, not after
  const plant::Plant model = plant::Plant::load(o.model_file);
  std::vector<Measurement> data;
  DataFiles names;  // per Measurement: its file (a file of several acquisitions, once for each)
  for (const auto& f : o.data_files) {
    throw_if_cancelled(o.settings.cancel);
    for (auto& m : load_acquisitions(f, o.dialect)) data.push_back(std::move(m)), names.push_back(f);
    if (data.back().has_encoder != data.front().has_encoder) {
      throw std::invalid_argument(f.string() + ": " + (data.back().has_encoder ? "has" : "has no") +
                                  " theta_motor_deg column, but " + o.data_files.front().string() + " " +
                                  (data.front().has_encoder ? "has one" : "has none") +
                                  ": files diagnosed together are replayed the same way (all with the encoder or all without)");
    }
  }
  std::vector<const Measurement*> files;
  for (const auto& m : data) files.push_back(&m);
  DiagnoseSettings s = o.settings;
  s.progress = s.progress || !o.quiet;
  const Diagnosis d = diagnose(model, files, s);
  throw_if_cancelled(s.cancel);
  std::filesystem::create_directories(o.out_dir);
  const std::string json_text = diagnosis_json(d, o.model_file, names);
  const std::string html = diagnosis_report_html(d, o.model_file, names);
  std::vector<hil::FileText> outputs{{o.out_dir / "diagnosis.json", {json_text}}, {o.out_dir / "report.html", {html}}};
  std::string model_text;
  if (!o.write_model.empty()) {
    if (o.write_model.has_parent_path()) std::filesystem::create_directories(o.write_model.parent_path());
    model_text = fitted_model_yaml(d, o.model_file, names);
    outputs.push_back({o.write_model, {model_text}});
  }
  hil::replace_files(outputs);  // all or none: never a new diagnosis beside an older report
  if (!o.quiet) {
    for (const auto& line : d.summary) std::printf("%s\n", line.c_str());
    if (!d.rounds.empty()) {
      std::printf("  round 1 ranking         variant              fit after  dBIC        earns\n");
      for (const auto& c : d.rounds.front().ranking) {
        std::printf("  %-22s %-20s %8.2f %% %11.4g  %s\n", c.effect.c_str(), c.variant.c_str(), c.fit_after_pct, c.delta_bic,
                    c.earns_place ? "yes" : "no");
      }
    }
    for (const auto& n : d.not_identifiable) std::printf("  not identifiable with the encoder: %s\n", n.effect.c_str());
    std::printf("  wrote %s and %s%s%s (%.1f s, %d replays)\n", (o.out_dir / "diagnosis.json").c_str(),
                (o.out_dir / "report.html").c_str(), o.write_model.empty() ? "" : " and ", o.write_model.c_str(), d.wall_s,
                d.evaluations);
  }
  return d;
}

}  // namespace hil::analysis
