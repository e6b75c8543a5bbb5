#include "hil/bench/campaign/checks.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <unordered_set>

#include "hil/bench/campaign/campaign.hpp"
#include "hil/bench/rt/rt_loop.hpp"
#include "hil/bench/rt/safety.hpp"
#include "hil/bench/rt/telemetry_record.hpp"
#include "hil/config.hpp"
#include "hil/units.hpp"

namespace hil::bench {
namespace {

using cfg::Node;

template <class E>
struct Named {
  const char* name;
  E value;
};
constexpr Named<CheckMetric> kMetrics[] = {
    {"iae_mpa_s", CheckMetric::iae_mpa_s},
    {"rmse_mpa", CheckMetric::rmse_mpa},
    {"stall_s_per_reversal", CheckMetric::stall_s_per_reversal},
    {"stall_vs_none", CheckMetric::stall_vs_none},
    {"touch_changes_per_reversal", CheckMetric::touch_changes_per_reversal},
    {"gap_error_deg", CheckMetric::gap_error_deg},
    {"gap_error_rel", CheckMetric::gap_error_rel},
    {"interlock_trips", CheckMetric::interlock_trips},
    {"compensation_events", CheckMetric::compensation_events},
};
constexpr Named<CheckSignal> kSignals[] = {
    {"pressure_error_mpa", CheckSignal::pressure_error_mpa},
    {"pressure_error_rel", CheckSignal::pressure_error_rel},
    {"gap_error_deg", CheckSignal::gap_error_deg},
    {"gap_error_rel", CheckSignal::gap_error_rel},
    {"safe_state", CheckSignal::safe_state},
};
constexpr Named<std::uint8_t> kEvents[] = {
    {"start", kEventStart},
    {"reference_change", kEventReferenceChange},
    {"reversal", kEventReversal},
    {"gap_change", kEventGapChange},
};

template <class E, std::size_t N>
E named(const Node& n, const Named<E> (&table)[N], const char* what) {
  const std::string s = n.text();
  std::vector<std::string> names;
  for (const auto& e : table) {
    if (s == e.name) return e.value;
    names.emplace_back(e.name);
  }
  std::string list;
  for (const auto& x : names) list += (list.empty() ? "" : ", ") + x;
  const std::string hint = cfg::closest(s, names);
  n.fail("unknown " + std::string(what) + " '" + s + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)") +
         "; known: " + list);
}

template <class E, std::size_t N>
const char* name_of(E v, const Named<E> (&table)[N]) {
  for (const auto& e : table)
    if (e.value == v) return e.name;
  return "?";
}

bool per_reversal(CheckMetric m) {
  return m == CheckMetric::stall_s_per_reversal || m == CheckMetric::stall_vs_none ||
         m == CheckMetric::touch_changes_per_reversal || m == CheckMetric::gap_error_deg || m == CheckMetric::gap_error_rel;
}

CheckSpec parse_one(const Node& item, const std::vector<std::string>& runs) {
  item.allow_keys({"name", "description", "runs", "metric", "signal", "from_reversal", "to_reversal", "reduce", "after",
                   "delay_s", "for_s", "min", "max"});
  CheckSpec s;
  s.name = item.text("name");
  item.at("name").require(cfg::plain_name(s.name),
                          "must be a plain name (letters, digits, '_', '-', '.'), it names the check in reports and JUnit");
  s.where = item.file().string() + ":" + std::to_string(item.line());
  if (auto r = item.find("runs")) {
    for (const Node& n : r->items()) {
      const std::string name = n.text();
      if (std::find(runs.begin(), runs.end(), name) == runs.end()) {
        const std::string hint = cfg::closest(name, runs);
        n.fail("the campaign has no run '" + name + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
      }
      n.require(std::find(s.runs.begin(), s.runs.end(), name) == s.runs.end(), "names this run twice");
      s.runs.push_back(name);
    }
    r->require(!s.runs.empty(), "names no run (leave 'runs' out for every run)");
  }
  item.require(item.has("metric") != item.has("signal"), "needs either 'metric' (of the run) or 'signal' (over time)");
  s.signal_check = item.has("signal");
  if (s.signal_check) {
    s.signal = named(item.at("signal"), kSignals, "signal");
    for (const char* k : {"reduce"}) {
      if (item.has(k)) item.at(k).fail("applies to a metric check, not to a signal (a signal's worst value is checked)");
    }
    if (auto a = item.find("after")) {
      s.after = 0;
      if (a->is_sequence()) {
        for (const Node& e : a->items()) s.after |= named(e, kEvents, "event");
        a->require(s.after != 0, "names no event");
      } else {
        s.after = named(*a, kEvents, "event");
      }
    }
    s.delay_s = item.number("delay_s", 0.0);
    if (auto d = item.find("delay_s")) d->require(std::isfinite(s.delay_s) && s.delay_s >= 0, "must be a time >= 0 s");
    if (auto f = item.find("for_s")) {
      s.for_s = f->number();
      f->require(std::isfinite(s.for_s) && s.for_s > 0, "must be a time > 0 s");
    }
    if (auto f = item.find("from_reversal")) {
      f->require((s.after & kEventReversal) == 0,
                 "counts reversals after the window's event; with 'after: reversal' use delay_s instead");
    }
  } else {
    s.metric = named(item.at("metric"), kMetrics, "metric");
    for (const char* k : {"after", "delay_s", "for_s"}) {
      if (item.has(k)) item.at(k).fail("applies to a signal check (a window in time), not to a metric of the whole run");
    }
    if (auto r = item.find("reduce")) {
      r->require(per_reversal(s.metric), "applies to a metric per reversal only");
      const std::string v = r->text();
      r->require(v == "mean" || v == "max", "must be mean or max (over the reversals)");
      s.reduce = v == "max" ? CheckReduce::max : CheckReduce::mean;
    }
    for (const char* k : {"from_reversal", "to_reversal"})
      if (auto f = item.find(k)) f->require(per_reversal(s.metric), "applies to a metric per reversal only");
    if (s.metric == CheckMetric::stall_vs_none) {
      item.at("metric").require(std::find(runs.begin(), runs.end(), "none") != runs.end(),
                                "needs a run named 'none' in the campaign (the stall without compensation)");
    }
  }
  if (auto f = item.find("from_reversal")) {
    f->require(f->integer() >= 1 && f->integer() <= 1000000, "must be a reversal number >= 1 (1 is the first)");
    s.from_reversal = static_cast<int>(f->integer());
  }
  if (auto t = item.find("to_reversal")) {
    t->require(!s.signal_check, "applies to a metric per reversal (a signal's window ends with for_s or the next event)");
    t->require(t->integer() >= std::max(s.from_reversal, 1) && t->integer() <= 1000000,
               "must be a reversal number >= from_reversal");
    s.to_reversal = static_cast<int>(t->integer());
  }
  for (const char* k : {"min", "max"}) {
    if (auto v = item.find(k)) {
      v->require(std::isfinite(v->number()), "must be a finite number");
      (std::string_view(k) == "min" ? s.min : s.max) = v->number();
    }
  }
  item.require(s.min || s.max, "needs a limit: 'max' and/or 'min'");
  if (s.min && s.max) item.at("max").require(*s.max >= *s.min, "is below min");
  return s;
}

double reduce(const std::vector<double>& v, CheckReduce how) {
  if (v.empty()) return kNaN;
  double acc = how == CheckReduce::max ? -std::numeric_limits<double>::infinity() : 0;
  for (double x : v) {
    if (std::isnan(x)) return kNaN;  // one unknown reversal makes the reduction unknown
    acc = how == CheckReduce::max ? std::max(acc, x) : acc + x;
  }
  return how == CheckReduce::max ? acc : acc / static_cast<double>(v.size());
}

// The per-reversal values of a metric over reversals first..last (1-based, inclusive).
std::vector<double> per_reversal_values(const RunSummary& s, CheckMetric m, int first, std::size_t last) {
  std::vector<double> out;
  for (std::size_t k = static_cast<std::size_t>(std::max(first, 1) - 1); k < std::min(last, s.reversals.size()); ++k) {
    const ReversalSummary& r = s.reversals[k];
    const double err = std::abs(r.gap_est_deg - r.gap_true_deg);
    switch (m) {
      case CheckMetric::stall_s_per_reversal:
      case CheckMetric::stall_vs_none: out.push_back(r.stall_s); break;
      case CheckMetric::touch_changes_per_reversal: out.push_back(r.touch_state_changes); break;
      case CheckMetric::gap_error_deg: out.push_back(err); break;
      case CheckMetric::gap_error_rel: out.push_back(r.gap_true_deg > 0 ? err / r.gap_true_deg : kNaN); break;
      default: break;
    }
  }
  return out;
}

std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.4g", v);
  return b;
}

// Sets the verdict and message of a result whose value is known (or not: skipped, `why`).
void judge(CheckResult& r, const CheckSpec& s, const std::string& what, const std::string& why_unknown) {
  r.min = s.min;
  r.max = s.max;
  if (!std::isfinite(r.value)) {
    r.verdict = Verdict::skipped;
    r.message = s.quantity() + " unknown: " + why_unknown;
    return;
  }
  std::string limit;
  if (s.max && r.value > *s.max) limit = " > max " + num(*s.max);
  if (s.min && r.value < *s.min) limit = " < min " + num(*s.min);
  r.verdict = limit.empty() ? Verdict::pass : Verdict::fail;
  if (limit.empty()) {
    limit = s.min && s.max ? " within [" + num(*s.min) + ", " + num(*s.max) + "]"
            : s.max        ? " <= max " + num(*s.max)
                           : " >= min " + num(*s.min);
  }
  r.message = s.quantity() + " = " + num(r.value) + limit + what;
}

}  // namespace

bool CheckSpec::applies_to(const std::string& run) const {
  return runs.empty() || std::find(runs.begin(), runs.end(), run) != runs.end();
}

std::string CheckSpec::quantity() const {
  return signal_check ? std::string("signal ") + name_of(signal, kSignals) : std::string(name_of(metric, kMetrics));
}

std::vector<CheckSpec> parse_checks(const Node& list, const std::vector<std::string>& runs) {
  std::vector<CheckSpec> out;
  // The names seen, looked up once per check: comparing each with every one before was quadratic
  // (9 000 checks took 22 s, on the server's request worker or on the CLI).
  std::unordered_set<std::string> names;
  for (const Node& item : list.items()) {
    CheckSpec s = parse_one(item, runs);
    if (!names.insert(s.name).second) item.at("name").require(false, "two checks have this name");
    out.push_back(std::move(s));
  }
  return out;
}

const char* to_string(Verdict v) noexcept {
  switch (v) {
    case Verdict::pass: return "pass";
    case Verdict::fail: return "fail";
    case Verdict::skipped: return "skipped";
  }
  return "?";
}

nlohmann::json CheckResult::to_json() const {
  const auto number_or_null = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  nlohmann::json j = {{"check", check},
                      {"run", run},
                      {"verdict", to_string(verdict)},
                      {"value", number_or_null(value)},
                      {"min", min ? nlohmann::json(*min) : nlohmann::json(nullptr)},
                      {"max", max ? nlohmann::json(*max) : nlohmann::json(nullptr)},
                      {"message", message}};
  if (samples > 0 || std::isfinite(at_s)) {
    j["at_s"] = number_or_null(at_s);
    j["samples"] = samples;
  }
  return j;
}

CheckTally tally(const std::vector<CheckResult>& results) {
  CheckTally t;
  for (const auto& r : results) {
    (r.verdict == Verdict::pass ? t.passed : r.verdict == Verdict::fail ? t.failed : t.skipped) += 1;
  }
  return t;
}

nlohmann::json checks_json(const std::vector<CheckResult>& results) {
  const CheckTally t = tally(results);
  nlohmann::json list = nlohmann::json::array();
  for (const auto& r : results) list.push_back(r.to_json());
  return {{"passed", t.passed}, {"failed", t.failed}, {"skipped", t.skipped}, {"results", list}};
}

struct InterlockCounter::Impl {
  Safety safety{SafetyConfig{}};
};

InterlockCounter::InterlockCounter() : impl_(std::make_unique<Impl>()) {}
InterlockCounter::~InterlockCounter() = default;

void InterlockCounter::add(const TelemetryRecord& r) noexcept {
  double value = 0, limit = 0;
  const bool trip = impl_->safety.check(false, false, r.step.p_meas_pa, value, limit) != Trip::none;
  if (trip && !tripping_) ++trips_;
  tripping_ = trip;
}

RunChecks::RunChecks(const Campaign& c, const std::string& run) : reversals_s_(c.reversals_s), run_(run) {
  for (const auto& s : c.checks) {
    if (!s.applies_to(run)) continue;
    specs_.push_back(&s);
    progress_.windows.emplace_back();
  }
}

void RunChecks::add(const TelemetryRecord& rec) noexcept {
  const StepRecord& r = rec.step;
  std::uint8_t events = have_prev_ ? 0 : kEventStart;
  if (have_prev_ && std::abs(r.p_ref_pa - prev_p_ref_pa_) > 1e-9 * std::max(std::abs(r.p_ref_pa), 1.0))
    events |= kEventReferenceChange;
  if (have_prev_ && std::abs(r.gap_true_rad - prev_gap_rad_) > 1e-12) events |= kEventGapChange;
  bool reversal = false;
  while (progress_.next_reversal < reversals_s_.size() && r.t_s >= reversals_s_[progress_.next_reversal] - 1e-9) {
    reversal = true;
    ++progress_.next_reversal;
  }
  if (reversal) events |= kEventReversal;
  prev_p_ref_pa_ = r.p_ref_pa;
  prev_gap_rad_ = r.gap_true_rad;
  have_prev_ = true;
  progress_.t_s = r.t_s;
  ++progress_.rows;

  for (std::size_t i = 0; i < specs_.size(); ++i) {
    const CheckSpec& s = *specs_[i];
    if (!s.signal_check) continue;
    Window& w = progress_.windows[i];
    // The window opens delay_s after the event or, with from_reversal, after the Nth reversal
    // since the event (the estimate is fitted a little after a reversal's contact).
    bool restarted = false;
    if (events & s.after) {
      w.event_t_s = s.from_reversal > 0 ? kNaN : r.t_s;
      w.reversals_since = 0;
      restarted = true;
    }
    if (reversal && !(events & s.after & ~kEventReversal) && ++w.reversals_since == s.from_reversal) {
      w.event_t_s = r.t_s;
      restarted = true;
    }
    // A window closes when it has lasted for_s or the next event starts another (the live
    // verdicts count them: a check is "passing" once one closed within its limit).
    const bool was_inside = w.inside;
    w.inside = false;
    if (std::isfinite(w.event_t_s)) {
      const double since = r.t_s - w.event_t_s;
      w.inside = since >= s.delay_s - 1e-9 && since < s.delay_s + s.for_s - 1e-9;
    }
    if (was_inside && (restarted || !w.inside)) ++w.closed;
    if (!w.inside) continue;
    double v = kNaN;
    const double p_err = std::abs(r.p_meas_pa - r.p_ref_pa);
    const double gap_err = std::abs(r.gap_est_rad - r.gap_true_rad);
    switch (s.signal) {
      case CheckSignal::pressure_error_mpa: v = units::pa_to_mpa(p_err); break;
      case CheckSignal::pressure_error_rel: v = r.p_ref_pa > 0 ? p_err / r.p_ref_pa : kNaN; break;
      case CheckSignal::gap_error_deg: v = units::rad_to_deg(gap_err); break;
      case CheckSignal::gap_error_rel: v = r.gap_true_rad > 0 ? gap_err / r.gap_true_rad : kNaN; break;
      case CheckSignal::safe_state: v = (rec.flags & kFlagSafeState) ? 1 : 0; break;
    }
    ++w.samples;
    if (!std::isfinite(v)) continue;
    ++w.valued;
    // The worst is the one farthest beyond the limits: above max, or below min when only a min is set.
    const double badness = s.max ? v : -v;
    if (badness > w.worst) {
      w.worst = badness;
      w.worst_t_s = r.t_s;
    }
  }
}

CheckResult RunChecks::signal_result(std::size_t i, const Window& w) const {
  const CheckSpec& s = *specs_[i];
  CheckResult r;
  r.check = s.name;
  r.run = run_;
  r.samples = w.samples;
  std::string why = "no period of the run was inside the check's windows";
  if (w.valued > 0) {
    r.value = s.max ? w.worst : -w.worst;
    r.at_s = w.worst_t_s;
  } else if (w.samples > 0) {
    why = "the run does not record what the signal needs (the true gap or pressure reference)";
  }
  char where[96];
  std::snprintf(where, sizeof where, " (worst at t = %.3f s, %ld periods checked)", r.at_s, r.samples);
  judge(r, s, where, why);
  return r;
}

std::vector<CheckResult> RunChecks::finish(const RunSummary& summary, long interlock_trips, const OtherRun& other) const {
  std::vector<CheckResult> out;
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    const CheckSpec& s = *specs_[i];
    if (s.signal_check) {
      out.push_back(signal_result(i, progress_.windows[i]));
      continue;
    }
    CheckResult r;
    r.check = s.name;
    r.run = run_;
    const bool per_rev = per_reversal(s.metric);
    const int first = s.from_reversal > 0                                                                  ? s.from_reversal
                      : (s.metric == CheckMetric::gap_error_deg || s.metric == CheckMetric::gap_error_rel) ? 2
                                                                                                           : 1;
    std::string why = "the run does not measure it (no valve angle on this rig?)";
    std::string what;
    if (per_rev) {
      const std::size_t n = summary.reversals.size();
      const std::size_t last = s.to_reversal > 0 ? std::min<std::size_t>(s.to_reversal, n) : n;
      what = " (" + std::string(s.reduce == CheckReduce::max ? "max" : "mean") + " over reversals " + std::to_string(first) +
             ".." + std::to_string(last) + ")";
      if (static_cast<std::size_t>(first) > n) why = "the run has " + std::to_string(n) + " reversals";
      r.value = reduce(per_reversal_values(summary, s.metric, first, last), s.reduce);
      if (s.metric == CheckMetric::stall_vs_none) {
        const RunSummary* none = other ? other("none") : nullptr;
        if (none == nullptr) {
          r.value = kNaN;
          why = "run 'none' did not run with it";
        } else {
          // mean: the mean stall over none's mean stall (the sweep's stall_vs_none); max: the
          // worst reversal's stall over none's at the same reversal (the paper's claim, per reversal).
          const auto mine = per_reversal_values(summary, CheckMetric::stall_s_per_reversal, first, last);
          const auto base = per_reversal_values(*none, CheckMetric::stall_s_per_reversal, first, last);
          if (s.reduce == CheckReduce::mean) {
            const double b = reduce(base, CheckReduce::mean);
            r.value = b > 0 ? r.value / b : kNaN;
          } else {
            std::vector<double> ratios;
            for (std::size_t k = 0; k < std::min(mine.size(), base.size()); ++k)
              ratios.push_back(base[k] > 0 ? mine[k] / base[k] : kNaN);
            r.value = reduce(ratios, CheckReduce::max);
          }
          if (!std::isfinite(r.value)) why = "run 'none' did not stall at those reversals";
        }
      }
    } else {
      switch (s.metric) {
        case CheckMetric::iae_mpa_s: r.value = summary.iae_mpa_s; break;
        case CheckMetric::rmse_mpa: r.value = summary.rmse_mpa; break;
        case CheckMetric::interlock_trips: r.value = static_cast<double>(interlock_trips); break;
        case CheckMetric::compensation_events: r.value = static_cast<double>(summary.compensation_events); break;
        default: break;
      }
    }
    judge(r, s, what, why);
    out.push_back(std::move(r));
  }
  return out;
}

}  // namespace hil::bench
