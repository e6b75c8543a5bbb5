// diagnose's words: the fitted parameters as text and the verdict with its summary.
#include <algorithm>
#include <cmath>

#include "diagnose_search.hpp"
#include "hil/units.hpp"
#include "text.hpp"
#include "velocity_signature.hpp"

namespace hil::analysis {

bool FittedParam::at_search_limit() const {
  // Within a thousandth of the range of an end: LM stops on a bound, not near it.
  const double tol = 1e-3 * (search_hi - search_lo);
  return std::isfinite(value) && std::isfinite(tol) && tol > 0 && (value <= search_lo + tol || value >= search_hi - tol);
}

std::string FittedParam::limit_text() const {
  if (!at_search_limit()) return {};
  return " (at the end of its search range, " + text::num(search_lo, 4) + " to " + text::num(search_hi, 4) +
         ": no measured value; the data want one beyond it, so this effect likely stands in for another, or the file's units "
         "or scaling are off)";
}

std::string FittedParam::plausibility_text() const {
  if (!implausible()) return {};
  return " (implausible: beyond " + credible_why +
         ", what the nominal plant makes credible; a real fault, or this effect stands in for another)";
}

std::string FittedParam::span_text() const {
  return located_between() ? " [" + text::num(lo, 4) + " to " + text::num(hi, 4) + " fit as well]" : std::string();
}

namespace detail {

std::string param_text(const FittedParam& p) {
  std::string s = p.key + " = " + text::num(p.value, 4);
  if (std::isfinite(p.sigma) && !p.at_search_limit()) s += " +- " + text::num(p.sigma, 2);
  s += p.span_text();
  s += p.limit_text();
  s += p.plausibility_text();
  if (p.file >= 0) s += " in file " + std::to_string(p.file + 1);
  return s;
}

// Several files: an event time found on the runs' joint clock (replay.hpp) becomes "file k, t s
// after its first row"; a step between two runs is at 0 s of the later file.
void localise_event_times(std::vector<FittedParam>& params, const ReplayData& data) {
  if (data.segments.size() < 2) return;
  for (auto& p : params) {
    if (!is_event_time(p.effect, p.key) || !std::isfinite(p.value)) continue;
    std::size_t k = 0;
    while (k + 1 < data.segments.size() && data.segments[k + 1].clock_offset_s <= p.value) ++k;
    p.file = static_cast<int>(k);
    p.value -= data.segments[k].clock_offset_s;
    p.lo -= data.segments[k].clock_offset_s;  // the span on the same file's clock: it may reach into
    p.hi -= data.segments[k].clock_offset_s;  // a neighbour's (below 0, or past the file's end)
  }
}

namespace {

// What the effects found leave where no candidate acts (issue 37; analysis/README.md, Verdict), in
// words, or "" when nothing: a ripple periodic in the drive angle or a misfit near zero velocity
// named in what remains; or, in the velocity band the misfit was named in before them, a residual
// still concentrated there by the band's own bars (velocity_signature.hpp: RMS inside at least
// twice the noise, mean square inside kBandContrast times the one outside; no cap on the rows, the
// band being the one found before, not searched again). The last is what a stick-slip leaves: a
// larger gap and a sensor lag take its mean lag and its flip with the direction, and the stuck
// phases stay in the band.
std::string structure_left(const FileFit& f) {
  const Diagnostics &before = f.before.diagnostics, &after = f.after.diagnostics;
  const double sigma = f.before.noise_sigma_pa, kpa = units::kPaPerKpa;
  if (!(sigma > 0) || at_noise_floor(f.after.error.rmse_pa, sigma)) return "";
  if (after.angle_ripple_period_deg > 0)
    return "what remains is periodic in the drive angle (a ripple of " + text::num(after.angle_ripple_kpa, 3) + " kPa with a " +
           text::num(after.angle_ripple_period_deg, 3) + " deg period)";
  if (after.velocity_band_deg_s > 0)
    return "what remains lives at |velocity| < " + text::num(after.velocity_band_deg_s, 3) + " deg/s (RMS " +
           text::num(after.velocity_band_rms_kpa, 3) + " kPa there, " + text::num(after.velocity_outside_rms_kpa, 3) +
           " kPa elsewhere)";
  if (before.velocity_band_deg_s > 0) {
    const BandSplit left = split_at(after.vs_drive_velocity, before.velocity_band_deg_s);
    if (left.rms_in_pa >= 2 * sigma &&
        left.rms_in_pa * left.rms_in_pa >= VelocityProfile::kBandContrast * left.rms_out_pa * left.rms_out_pa)
      return "the misfit was named at |velocity| < " + text::num(before.velocity_band_deg_s, 3) +
             " deg/s before them, and what remains is there: " + text::num(left.rms_in_pa / kpa, 3) + " kPa RMS (" +
             text::num(left.rms_in_pa / sigma, 3) + " times the noise) in " + text::num(100 * left.rows_share, 3) +
             " % of the rows, " + text::num(left.rms_out_pa / kpa, 3) + " kPa elsewhere";
  }
  return "";
}

}  // namespace

void write_verdict(Diagnosis& d, std::size_t n_files) {
  // The verdict in words.
  auto& out = d.summary;
  const std::string fit_line =
      "Fit " + text::fixed(d.fit_before_pct, 2) + " % -> " + text::fixed(d.fit_after_pct, 2) + " % (noise floor " +
      text::fixed(d.noise_floor_fit_pct, 2) + " %); RMSE " + text::num(d.rmse_before_pa / units::kPaPerKpa, 3) + " -> " +
      text::num(d.rmse_after_pa / units::kPaPerKpa, 3) + " kPa (noise " + text::num(d.noise_sigma_pa / units::kPaPerKpa, 3) +
      " kPa)" + (n_files > 1 ? ", over all " + std::to_string(n_files) + " files." : ".");
  // Several files: say what was shared, and how each file ends.
  auto per_file = [&](bool after) {
    if (n_files < 2) return;
    std::string line = "Per file:";
    for (std::size_t i = 0; i < d.files.size(); ++i) {
      const ResidualReport& r = after ? d.files[i].after : d.files[i].before;
      line += (i ? "; " : " ") + std::string("file ") + std::to_string(i + 1) + " " + text::fixed(r.fit_pct, 2) + " % (floor " +
              text::fixed(r.noise_floor_fit_pct, 2) + " %)";
    }
    out.push_back(line + ".");
  };
  // The effects added, with their parameters.
  auto found_list = [&](const std::string& sep) {
    std::string list;
    for (const auto& c : d.added) {
      std::string ps;
      for (const auto& p : c.parameters) ps += (ps.empty() ? "" : ", ") + param_text(p);
      list += (list.empty() ? "" : sep) + c.effect + " (" + c.variant + ": " + ps + ")";
    }
    return list;
  };
  // Each file's residual signature before any effect was added.
  auto signature_before = [&] {
    for (std::size_t i = 0; i < d.files.size(); ++i) {
      if (n_files > 1) out.push_back("File " + std::to_string(i + 1) + ":");
      for (const auto& line : d.files[i].before.signature) out.push_back(line);
    }
  };
  // Effects that moved the fit but leave structure where no candidate acts stand in for an effect
  // outside the list: the file is not explained (acceptance of issue 37).
  std::string left;
  if (d.explained && !d.at_noise_floor) {
    for (std::size_t i = 0; i < d.files.size() && left.empty(); ++i) {
      left = structure_left(d.files[i]);
      if (!left.empty() && n_files > 1) left = "in file " + std::to_string(i + 1) + ", " + left;
    }
  }
  if (!left.empty()) {
    d.explained = false;
    d.verdict = "unexplained";
    out.push_back("Not explained: " + found_list("; ") + " earned their place, but the residual stays " +
                  text::num(d.rmse_after_pa / d.noise_sigma_pa, 3) + " times the noise and " + left +
                  ", structure no candidate holds: they stand in for part of an effect outside the list. The misfit's "
                  "signature before them:");
    signature_before();
    out.push_back(fit_line);
    per_file(true);
  } else if (d.explained) {
    out.push_back("Found: " + found_list("; then ") + ".");
    if (n_files > 1) {
      std::string per_file_list;
      for (const auto& c : d.added)
        for (const auto& p : c.parameters)
          if (p.file >= 0)
            per_file_list += (per_file_list.empty() ? "" : ", ") + p.key + " (file " + std::to_string(p.file + 1) + ", " +
                             text::num(p.value, 4) + " s after its first row)";
      out.push_back(
          "Fitted to " + std::to_string(n_files) + " files of one rig together (in the order they were run): " +
          (per_file_list.empty()
               ? std::string("every parameter above is shared by all of them")
               : "every parameter above is shared by all of them except the step time, which is per file: " + per_file_list +
                     "; the files before it have the gap before the step, the files after "
                     "it the gap after the step") +
          "; erosion and drifts count from each file's first row.");
    }
    out.push_back(fit_line);
    per_file(true);
    for (const auto& c : d.correlations) {
      if (!c.indistinguishable) continue;
      out.push_back("On this file " + c.effect_a + " and " + c.effect_b + " can hardly be told apart: " + c.key_a + " and " +
                    c.key_b + " correlate at " + text::num(c.rho, 3) +
                    " in the joint fit and neither is pinned to 10 % of its change (a change of one is largely undone "
                    "by the other); a run with other motion or pressure levels separates them.");
    }
    for (const auto& r : d.revisions) out.push_back("Revisited: " + r + ".");
    for (const auto& r : d.rivals) {
      out.push_back("Not told apart on this file: " + r.alternative + " (" + r.variant + ") in place of " + r.effect +
                    ", the others refitted, fits " + text::fixed(r.fit_pct, 2) + " % against " + text::fixed(d.fit_after_pct, 2) +
                    " % (whole-model BIC " + (r.dbic >= 0 ? "+" : "") + text::num(r.dbic, 3) +
                    "; an effect earns its place at -10); either may be the cause. A run with other motion or pressure "
                    "levels, the encoder, or several files fitted together (--data a --data b) separate them.");
    }
    if (d.at_noise_floor) {
      d.verdict = "explained";
    } else {
      d.verdict = "partly_explained";
      std::string remains;
      for (std::size_t i = 0; i < d.files.size(); ++i)
        remains += (n_files > 1 ? (i ? " File " : "File ") + std::to_string(i + 1) + ": " : std::string()) +
                   text::join(d.files[i].after.signature, " ");
      out.push_back("Partly explained: each effect above earned its place, but the residual is still " +
                    text::num(d.rmse_after_pa / d.noise_sigma_pa, 3) +
                    " times the noise, so something else is missing, and the effects found may stand in for it. "
                    "What remains: " +
                    remains);
    }
  } else if (at_noise_floor(d.rmse_before_pa, d.noise_sigma_pa)) {
    d.verdict = "nothing_missing";
    d.at_noise_floor = true;
    out.push_back("Nothing is missing: the model fits at the noise floor and no candidate earns its place.");
    out.push_back(fit_line);
    per_file(false);
  } else {
    d.verdict = "unexplained";
    out.push_back(
        "No candidate explains the residual: none earns its place, so none is named. The missing effect is "
        "something else; its signature:");
    signature_before();
  }
  if (!d.rescue.empty()) out.push_back("Round 1, pair rescue: " + d.rescue + ".");
  // What the files themselves show comes first: a verdict on a file with a hole or stale readings
  // is read with that in mind.
  std::vector<std::string> log_lines;
  for (std::size_t i = 0; i < d.files.size(); ++i)
    for (const auto* lines : {&d.files[i].before.run_notes, &d.files[i].before.log_warnings})
      for (const auto& w : *lines) log_lines.push_back(n_files > 1 ? "File " + std::to_string(i + 1) + ": " + w : w);
  out.insert(out.begin(), log_lines.begin(), log_lines.end());
}

}  // namespace detail
}  // namespace hil::analysis
