// A sweep's point: its campaign (the base with the point's axis values written in) and its run,
// the metrics of one row of sweep.csv.
#include <cmath>
#include <stdexcept>

#include "hil/bench/campaign/sim.hpp"
#include "hil/bench/campaign/sweep.hpp"
#include "hil/bench/rt/safety.hpp"
#include "hil/config.hpp"
#include "sweep_paths.hpp"

namespace hil::bench {

using namespace sweep_detail;
using json = nlohmann::json;

PointMaker::PointMaker(const SweepPlan& plan)
    : plan_(plan),
      campaign_(load_yaml(plan.campaign_yaml, "the sweep's base campaign")),
      plant_(load_yaml(plan.plant_yaml, "the sweep's base plant")) {}

PointYaml PointMaker::yaml(long p) const {
  const SweepPlan& plan = plan_;
  if (p < 0 || p >= plan.size()) throw std::out_of_range("sweep " + plan.name + " has no point " + std::to_string(p));
  YAML::Node campaign = YAML::Clone(campaign_);
  YAML::Node plant = YAML::Clone(plant_);
  const auto& values = plan.points[static_cast<std::size_t>(p)];
  // Values first, then the increments onto what the values made.
  for (const bool relative : {false, true}) {
    for (std::size_t i = 0; i < plan.axes.size(); ++i) {
      const SweepAxis& axis = plan.axes[i];
      if (axis.relative_to.empty() == relative) continue;
      const auto path = parse_path(axis.path);
      YAML::Node at = walk_checked(path->plant ? plant : campaign, *path);
      if (!relative) {
        at = values[i];
        continue;
      }
      const auto base_path = parse_path(axis.relative_to);
      const std::string base = walk_checked(base_path->plant ? plant : campaign, *base_path).as<std::string>();
      // As a YAML number (initial_deg: +1.0, values: [+0.5]), like every number of the campaign.
      double b = 0, d = 0;
      if (!cfg::parse_number(base, b)) {
        throw cfg::Error(axis.path + ": relative to " + axis.relative_to + " = '" + base + "', which is no number");
      }
      if (!cfg::parse_number(values[i], d)) throw cfg::Error(axis.path + ": the increment '" + values[i] + "' is no number");
      at = shortest(b + d);
    }
  }
  // Only the sweep's runs, so the point's file reproduces exactly what the sweep ran.
  YAML::Node runs(YAML::NodeType::Sequence);
  for (const auto& r : campaign["runs"]) {
    const YAML::Node name = r["name"];
    if (name.IsScalar() && std::find(plan.runs.begin(), plan.runs.end(), name.as<std::string>()) != plan.runs.end()) {
      runs.push_back(r);
    }
  }
  campaign["runs"] = runs;
  // And only the checks of those runs (a check of a run the sweep leaves out would name no run).
  const YAML::Node checks = static_cast<const YAML::Node&>(campaign)["checks"];
  if (checks && checks.IsSequence()) {
    const auto swept = [&](const std::string& r) { return std::find(plan.runs.begin(), plan.runs.end(), r) != plan.runs.end(); };
    YAML::Node kept(YAML::NodeType::Sequence);
    for (const YAML::Node& check : checks) {
      YAML::Node copy = YAML::Clone(check);
      const YAML::Node& read = copy;
      if (read.IsMap() && read["metric"] && read["metric"].IsScalar() && read["metric"].as<std::string>() == "stall_vs_none" &&
          !swept("none"))
        continue;
      if (read.IsMap() && read["runs"] && read["runs"].IsSequence()) {
        YAML::Node names(YAML::NodeType::Sequence);
        for (const YAML::Node& n : read["runs"])
          if (n.IsScalar() && swept(n.as<std::string>())) names.push_back(n);
        if (names.size() == 0) continue;
        copy["runs"] = names;
      }
      kept.push_back(copy);
    }
    campaign["checks"] = kept;
  }
  // A reference read from a CSV file: from where the base campaign found it, wherever the point's
  // campaign is written.
  // (Read through const nodes, tested before use: a mutable node's operator[] would add the keys
  // it looks for, and a missing one is an invalid node.)
  const YAML::Node& read_only = campaign;
  const YAML::Node reference = read_only["reference"];
  const YAML::Node profile = reference && reference.IsMap() ? reference["profile"] : YAML::Node();
  if (profile && profile.IsSequence()) {
    for (std::size_t i = 0; i < profile.size(); ++i) {
      const YAML::Node item = profile[i];
      if (!item.IsMap() || !item["csv"] || !item["csv"].IsMap() || !item["csv"]["file"] || !item["csv"]["file"].IsScalar())
        continue;
      const std::string file = item["csv"]["file"].as<std::string>();
      if (std::filesystem::path(file).is_relative()) {
        YAML::Node target = campaign["reference"]["profile"][i]["csv"]["file"];
        target = (plan.campaign_dir / file).lexically_normal().string();
      }
    }
  }
  if (!campaign["name"]) campaign["name"] = plan.name;
  campaign["plant"] = "plant.yaml";
  YAML::Emitter c, pl;
  c << campaign;
  pl << plant;
  return {std::string(c.c_str()) + "\n", std::string(pl.c_str()) + "\n"};
}

Campaign PointMaker::campaign(long p) const {
  const PointYaml y = yaml(p);
  const std::string where = "sweep point " + std::to_string(p);
  return load_campaign_text(y.campaign, where + " campaign.yaml", plan_.campaign_dir, y.plant, where + " plant.yaml");
}

PointYaml point_yaml(const SweepPlan& plan, long p) { return PointMaker(plan).yaml(p); }

std::vector<double> PointMaker::run(long p, const std::atomic<bool>* cancel) const {
  const SweepPlan& plan = plan_;
  // The campaign the plan's check loaded, where it kept it: the same function of the same text.
  const auto& kept = plan.checked_campaigns;
  const Campaign* checked =
      kept && p >= 0 && p < static_cast<long>(kept->size()) ? (*kept)[static_cast<std::size_t>(p)].get() : nullptr;
  std::optional<Campaign> loaded;
  const Campaign& c = checked != nullptr ? *checked : loaded.emplace(campaign(p));
  std::vector<std::string> names;
  for (const auto& r : c.runs) names.push_back(r.name);
  if (names != plan.runs)
    throw std::runtime_error("sweep point " + std::to_string(p) + ": the campaign's runs are not the plan's");
  struct PerRun {
    double iae = 0, stall = kNoValue, touch = kNoValue, gap_err = kNoValue;
    long trips = 0, checks_failed = 0;
  };
  std::vector<PerRun> out;
  std::vector<RunSummary> summaries;
  std::vector<std::unique_ptr<RunChecks>> checks;
  double none_stall = kNoValue;
  for (const RunSpec& run : c.runs) {
    // What the bench's default interlocks would have tripped on (the simulation has none), and
    // the campaign's checks, as `hilbench sim` evaluates them.
    InterlockCounter interlocks;
    checks.push_back(std::make_unique<RunChecks>(c, run.name));
    RunChecks& run_checks = *checks.back();
    long step = 0;
    const RunSummary s = summarise_run(c, run, [&](const TelemetryRecord& r) {
      if ((++step & 1023) == 0 && cancel != nullptr && cancel->load(std::memory_order_relaxed)) {
        throw Cancelled("sweep point " + std::to_string(p) + " abandoned");
      }
      interlocks.add(r);
      run_checks.add(r);
    });
    PerRun m;
    m.iae = s.iae_mpa_s;
    m.trips = interlocks.trips();
    const std::size_t n = s.reversals.size();
    if (n > 0) {
      double stall = 0;
      for (const auto& r : s.reversals) stall += r.stall_s;
      m.stall = stall / static_cast<double>(n);
      m.touch = static_cast<double>(s.touch_state_changes) / static_cast<double>(n);
    }
    if (n > 1) {  // the first reversal is where the estimate is learnt
      double err = 0;
      for (std::size_t k = 1; k < n; ++k) err += std::abs(s.reversals[k].gap_est_deg - s.reversals[k].gap_true_deg);
      m.gap_err = err / static_cast<double>(n - 1);
    }
    if (run.name == "none") none_stall = m.stall;
    out.push_back(m);
    summaries.push_back(s);
  }
  // The checks once every run is through: a check may compare with another run (stall_vs_none).
  const auto other = [&](const std::string& name) -> const RunSummary* {
    for (std::size_t i = 0; i < c.runs.size(); ++i)
      if (c.runs[i].name == name) return &summaries[i];
    return nullptr;
  };
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i].checks_failed = tally(checks[i]->finish(summaries[i], out[i].trips, other)).failed;
  }
  const bool has_none = std::find(plan.runs.begin(), plan.runs.end(), "none") != plan.runs.end();
  std::vector<double> metrics;
  for (const PerRun& m : out) {
    metrics.push_back(m.iae);
    metrics.push_back(m.stall);
    if (has_none) metrics.push_back(none_stall > 0 ? m.stall / none_stall : kNoValue);
    metrics.push_back(m.touch);
    metrics.push_back(m.gap_err);
    metrics.push_back(static_cast<double>(m.trips));
    metrics.push_back(static_cast<double>(m.checks_failed));
  }
  return metrics;
}

bool point_passes(const SweepPlan& plan, const std::vector<double>& metrics) {
  const auto names = plan.metric_names();
  // A failed check of the point's campaign is a failed point, whatever the thresholds say.
  static constexpr std::string_view kChecksFailed = ".checks_failed";
  for (std::size_t i = 0; i < names.size() && i < metrics.size(); ++i) {
    const std::string_view n = names[i];
    if (n.size() > kChecksFailed.size() && n.substr(n.size() - kChecksFailed.size()) == kChecksFailed && metrics[i] != 0)
      return false;
  }
  for (const auto& t : plan.thresholds) {
    const auto at = std::find(names.begin(), names.end(), t.metric);
    if (at == names.end()) return false;
    const double v = metrics.at(static_cast<std::size_t>(at - names.begin()));
    if (!std::isfinite(v)) return false;
    if (t.min && v < *t.min) return false;
    if (t.max && v > *t.max) return false;
  }
  return true;
}

}  // namespace hil::bench
