#include "hil/bench/campaign/sweep.hpp"

#include <algorithm>
#include <atomic>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <thread>

#include <yaml-cpp/yaml.h>

#include "hil/bench/campaign/sim.hpp"
#include "hil/bench/rt/safety.hpp"
#include "hil/config.hpp"
#include "hil/plant/rng.hpp"
#include "hil/progress_line.hpp"
#include "hil/text_file.hpp"
#include "sweep_words.hpp"

namespace hil::bench {
namespace {

using cfg::Node;
using json = nlohmann::json;

constexpr double kNoValue = std::numeric_limits<double>::quiet_NaN();

// A number as the shortest text that reads back as the same double: the same value always
// prints the same, whatever computed it.
std::string shortest(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

// FNV-1a, 64 bit: enough to tell that a sweep file changed since its folder was planned.
std::uint64_t fnv1a(std::string_view text, std::uint64_t h = 0xcbf29ce484222325ULL) {
  for (unsigned char ch : text) {
    h ^= ch;
    h *= 0x100000001b3ULL;
  }
  return h;
}

std::string hex16(std::uint64_t h) {
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}

std::string content_hash(const std::filesystem::path& file) {
  return hex16(fnv1a(read_text_file(file, "a file the sweep reads")));
}

// One step of an axis path: a mapping key or a sequence index.
struct Step {
  std::string key;
  long index = -1;  // >= 0: a sequence index
};

struct AxisPath {
  bool plant = false;  // in the plant file, else in the campaign file
  std::vector<Step> steps;
};

// "campaign.gap.changes[0].drift.to_deg" -> campaign file, gap / changes / [0] / drift / to_deg.
// "controller.x" stands for campaign.controller.x. Empty on a malformed path.
std::optional<AxisPath> parse_path(const std::string& text) {
  AxisPath p;
  std::vector<std::string> parts;
  std::string part;
  for (char ch : text) {
    if (ch == '.') {
      parts.push_back(part);
      part.clear();
    } else {
      part += ch;
    }
  }
  parts.push_back(part);
  if (parts.size() < 2) return std::nullopt;
  if (parts[0] == "plant") {
    p.plant = true;
  } else if (parts[0] == "controller") {
    p.steps.push_back({"controller"});
  } else if (parts[0] != "campaign") {
    return std::nullopt;
  }
  for (std::size_t i = 1; i < parts.size(); ++i) {
    std::string s = parts[i];
    const auto bracket = s.find('[');
    const std::string key = s.substr(0, bracket);
    if (key.empty()) return std::nullopt;
    p.steps.push_back({key});
    for (auto at = bracket; at != std::string::npos;) {
      const auto close = s.find(']', at);
      if (close == std::string::npos || close == at + 1) return std::nullopt;
      long index = 0;
      const auto r = std::from_chars(s.data() + at + 1, s.data() + close, index);
      if (r.ec != std::errc() || r.ptr != s.data() + close || index < 0) return std::nullopt;
      p.steps.push_back({"", index});
      at = close + 1 == s.size() ? std::string::npos : close + 1;
      if (at != std::string::npos && s[at] != '[') return std::nullopt;
    }
  }
  return p;
}

std::string describe(const std::vector<Step>& steps, std::size_t n) {
  std::string s;
  for (std::size_t i = 0; i < n; ++i) {
    if (steps[i].index >= 0) {
      s += "[" + std::to_string(steps[i].index) + "]";
    } else {
      s += (s.empty() ? "" : ".") + steps[i].key;
    }
  }
  return s.empty() ? "the top level" : "'" + s + "'";
}

// The scalar `path` names in `root`; fails at `where` (the sweep file's axis) when it is not one.
// Read-only: a const node's operator[] never adds the key it looks for.
void walk(const YAML::Node& root, const AxisPath& path, const Node& where, const std::string& file_name) {
  YAML::Node at = root;
  for (std::size_t i = 0; i < path.steps.size(); ++i) {
    const Step& s = path.steps[i];
    const YAML::Node& here = at;
    if (s.index >= 0) {
      if (!here.IsSequence() || static_cast<std::size_t>(s.index) >= here.size()) {
        where.fail(file_name + " has no item [" + std::to_string(s.index) + "] in " + describe(path.steps, i) +
                   (here.IsSequence() ? " (it has " + std::to_string(here.size()) + ")" : " (not a list)"));
      }
      at.reset(here[static_cast<std::size_t>(s.index)]);
      continue;
    }
    if (!here.IsMap() || !here[s.key]) {
      std::vector<std::string> keys;
      if (at.IsMap())
        for (const auto& kv : at) keys.push_back(kv.first.as<std::string>());
      const std::string hint = cfg::closest(s.key, keys);
      where.fail(file_name + " has no key '" + s.key + "' in " + describe(path.steps, i) +
                 (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
    }
    at.reset(here[s.key]);
  }
  if (!at.IsScalar())
    where.fail("names " + describe(path.steps, path.steps.size()) + " of " + file_name + ", which is no single value");
}

// Mutable walk of an already checked path (the tree is a clone of the checked base).
YAML::Node walk_checked(YAML::Node root, const AxisPath& path) {
  YAML::Node at = root;
  for (const Step& s : path.steps) {
    if (s.index >= 0) {
      at.reset(at[static_cast<std::size_t>(s.index)]);
    } else {
      at.reset(at[s.key]);
    }
  }
  return at;
}

// The random axes' draws: a generator seeded from (seed, point, axis) alone, never from the order
// the points run in.
double draw(const SweepAxis& a, std::uint64_t seed, long point, std::size_t axis) {
  plant::Rng rng(seed * 0x9e3779b97f4a7c15ULL + static_cast<std::uint64_t>(point) * 0xd1b54a32d192ed03ULL +
                 (axis + 1) * 0x94d049bb133111ebULL);
  return a.kind == AxisKind::uniform ? a.a + (a.b - a.a) * rng.uniform() : a.a + a.b * rng.gaussian();
}

SweepAxis read_axis(const Node& n, const YAML::Node& campaign, const YAML::Node& plant, const std::string& campaign_name,
                    const std::string& plant_name) {
  n.allow_keys({"path", "values", "range", "uniform", "normal", "relative_to", "label", "unit"});
  SweepAxis a;
  a.path = n.text("path");
  read_axis_words(n, a);
  const auto path = parse_path(a.path);
  if (!path) {
    n.at("path").fail("'" + a.path +
                      "' is no axis path: campaign.<key>..., plant.<key>... or controller.<key>..., keys separated by '.', list "
                      "items as [n]");
  }
  walk(path->plant ? plant : campaign, *path, n.at("path"), path->plant ? plant_name : campaign_name);
  if (!path->plant && !path->steps.empty()) {
    // What names the outputs is not a condition: the campaign's name and plant file, run names.
    const auto& s = path->steps;
    n.at("path").require(s.size() != 1 || (s[0].key != "name" && s[0].key != "plant"),
                         "the campaign's name and plant file cannot be an axis (sweep the plant's values instead)");
    n.at("path").require(!(s.size() == 3 && s[0].key == "runs" && s[2].key == "name"),
                         "run names cannot be an axis: they name the sweep's metrics");
  }
  if (auto rel = n.find("relative_to")) {
    a.relative_to = rel->text();
    const auto base = parse_path(a.relative_to);
    if (!base) rel->fail("'" + a.relative_to + "' is no axis path");
    walk(base->plant ? plant : campaign, *base, *rel, base->plant ? plant_name : campaign_name);
    rel->require(a.relative_to != a.path, "an axis cannot be relative to itself");
  }
  int kinds = 0;
  for (const char* k : {"values", "range", "uniform", "normal"}) kinds += n.has(k) ? 1 : 0;
  n.require(kinds == 1, "an axis needs exactly one of values, range, uniform, normal");
  if (auto v = n.find("values")) {
    a.kind = AxisKind::list;
    v->require(v->is_sequence() && !v->items().empty(), "needs a non-empty list of values");
    for (const Node& item : v->items()) {
      item.require(item.is_scalar(), "each value must be a single value");
      if (!a.relative_to.empty()) item.number();  // an increment: a number
      a.values.push_back(item.text());
    }
  } else if (auto r = n.find("range")) {
    a.kind = AxisKind::range;
    r->allow_keys({"from", "to", "count", "scale"});
    const double from = r->number("from"), to = r->number("to");
    const long long count = r->at("count").integer();
    r->at("count").require(count >= 1 && count <= 10000, "must be a whole number in [1, 10000]");
    r->at("count").require(count > 1 || from == to, "one value needs from = to");
    const std::string scale = r->text("scale", "linear");
    if (auto s = r->find("scale")) s->require(scale == "linear" || scale == "log", "must be linear or log");
    if (scale == "log") r->require(from > 0 && to > 0, "a log range needs from > 0 and to > 0");
    for (long long i = 0; i < count; ++i) {
      const double f = count == 1 ? 0.0 : static_cast<double>(i) / static_cast<double>(count - 1);
      const double v = i == count - 1   ? to
                       : scale == "log" ? std::exp(std::log(from) + f * (std::log(to) - std::log(from)))
                                        : from + f * (to - from);
      // 12 significant digits: 0.005 rather than 0.005000000000000002 from exp(log(...)).
      char rounded[32];
      std::snprintf(rounded, sizeof rounded, "%.12g", v);
      a.values.push_back(shortest(std::strtod(rounded, nullptr)));
    }
  } else if (auto u = n.find("uniform")) {
    a.kind = AxisKind::uniform;
    u->allow_keys({"low", "high"});
    a.a = u->number("low");
    a.b = u->number("high");
    u->at("high").require(a.b > a.a, "must be above low");
  } else {
    const Node d = n.at("normal");
    a.kind = AxisKind::normal;
    d.allow_keys({"mean", "sd"});
    a.a = d.number("mean");
    a.b = d.number("sd");
    d.at("sd").require(a.b > 0, "must be > 0");
  }
  return a;
}

std::vector<std::string> axis_paths(const std::vector<SweepAxis>& axes) {
  std::vector<std::string> paths;
  for (const auto& a : axes) paths.push_back(a.path);
  return paths;
}

void require_metric(const Node& where, const std::string& metric, const std::vector<std::string>& metrics) {
  if (std::find(metrics.begin(), metrics.end(), metric) != metrics.end()) return;
  const std::string hint = cfg::closest(metric, metrics);
  where.fail("no metric '" + metric + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)") +
             "; metrics are <run>.iae_mpa_s, .stall_s_per_reversal, .stall_vs_none, .touch_changes_per_reversal, "
             ".gap_error_deg, .interlock_trips, .checks_failed");
}

const SweepAxis& grid_axis(const Node& where, const std::string& path, const std::vector<SweepAxis>& axes) {
  for (const auto& a : axes) {
    if (a.path != path) continue;
    where.require(!a.random(), "'" + path + "' is a distribution axis; a map's axes and slices need a list or range axis");
    return a;
  }
  const std::string hint = cfg::closest(path, axis_paths(axes));
  where.fail("no axis '" + path + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
}

YAML::Node load_yaml(const std::string& text, const std::string& origin) {
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(origin + ": " + e.what());
  }
}

}  // namespace

std::vector<std::string> SweepPlan::metric_names() const {
  const bool has_none = std::find(runs.begin(), runs.end(), "none") != runs.end();
  std::vector<std::string> names;
  for (const auto& r : runs) {
    for (const char* m : {"iae_mpa_s", "stall_s_per_reversal", "stall_vs_none", "touch_changes_per_reversal", "gap_error_deg",
                          "interlock_trips", "checks_failed"}) {
      if (std::string_view(m) == "stall_vs_none" && !has_none) continue;
      names.push_back(r + "." + m);
    }
  }
  return names;
}

nlohmann::json SweepPlan::to_json() const {
  json axes_j = json::array();
  for (const auto& a : axes) {
    static const char* kinds[] = {"list", "range", "uniform", "normal"};
    axes_j.push_back({{"path", a.path},
                      {"kind", kinds[static_cast<int>(a.kind)]},
                      {"values", a.values},
                      {"a", a.a},
                      {"b", a.b},
                      {"relative_to", a.relative_to}});
    axis_words_to_json(a, axes_j.back());
  }
  json thresholds_j = json::array();
  for (const auto& t : thresholds) {
    json b = {{"metric", t.metric}};
    if (t.min) b["min"] = *t.min;
    if (t.max) b["max"] = *t.max;
    thresholds_j.push_back(b);
  }
  json maps_j = json::array();
  for (const auto& m : maps) {
    json slice = json::array();
    for (const auto& [k, v] : m.slice) slice.push_back({k, v});
    maps_j.push_back({{"metric", m.metric}, {"x", m.x}, {"y", m.y}, {"reduce", m.reduce}, {"slice", slice}});
    map_bound_to_json(m, maps_j.back());
  }
  json inputs = json::array();
  for (const auto& f : input_files) inputs.push_back({{"path", f.path.string()}, {"fnv1a", f.hash}});
  return {{"format", "hilbench sweep plan 1"},
          {"input_files", inputs},
          {"name", name},
          {"description", description},
          {"hash", hash},
          {"campaign_yaml", campaign_yaml},
          {"plant_yaml", plant_yaml},
          {"campaign_dir", campaign_dir.string()},
          {"runs", runs},
          {"seed", seed},
          {"samples", samples},
          {"axes", axes_j},
          {"thresholds", thresholds_j},
          {"maps", maps_j},
          {"worst_by", worst_by},
          {"points", points}};
}

SweepPlan SweepPlan::from_json(const nlohmann::json& j, const std::string& origin) {
  try {
    if (j.value("format", "") != "hilbench sweep plan 1") throw std::runtime_error("not a sweep plan of this hilbench");
    SweepPlan p;
    p.name = j.at("name").get<std::string>();
    p.description = j.at("description").get<std::string>();
    p.hash = j.at("hash").get<std::string>();
    p.campaign_yaml = j.at("campaign_yaml").get<std::string>();
    p.plant_yaml = j.at("plant_yaml").get<std::string>();
    p.campaign_dir = j.at("campaign_dir").get<std::string>();
    p.runs = j.at("runs").get<std::vector<std::string>>();
    p.seed = j.at("seed").get<std::uint64_t>();
    p.samples = j.at("samples").get<long>();
    for (const auto& a : j.at("axes")) {
      SweepAxis x;
      x.path = a.at("path").get<std::string>();
      const std::string kind = a.at("kind").get<std::string>();
      if (kind != "list" && kind != "range" && kind != "uniform" && kind != "normal")
        throw std::runtime_error("axis '" + x.path + "': no kind '" + kind + "'");
      x.kind = kind == "list"      ? AxisKind::list
               : kind == "range"   ? AxisKind::range
               : kind == "uniform" ? AxisKind::uniform
                                   : AxisKind::normal;
      x.values = a.at("values").get<std::vector<std::string>>();
      x.a = a.at("a").get<double>();
      x.b = a.at("b").get<double>();
      x.relative_to = a.at("relative_to").get<std::string>();
      axis_words_from_json(a, x);
      p.axes.push_back(std::move(x));
    }
    for (const auto& t : j.at("thresholds")) {
      SweepBound b{t.at("metric").get<std::string>()};
      if (t.contains("min")) b.min = t.at("min").get<double>();
      if (t.contains("max")) b.max = t.at("max").get<double>();
      p.thresholds.push_back(std::move(b));
    }
    for (const auto& m : j.at("maps")) {
      SweepMap s{m.at("metric").get<std::string>(), m.at("x").get<std::string>(), m.at("y").get<std::string>(),
                 m.at("reduce").get<std::string>()};
      for (const auto& kv : m.at("slice")) s.slice.emplace_back(kv.at(0).get<std::string>(), kv.at(1).get<std::string>());
      map_bound_from_json(m, s);
      p.maps.push_back(std::move(s));
    }
    p.worst_by = j.at("worst_by").get<std::string>();
    p.points = j.at("points").get<std::vector<std::vector<std::string>>>();
    if (j.contains("input_files")) {  // plans written before it have none
      for (const auto& f : j.at("input_files")) {
        p.input_files.push_back({f.at("path").get<std::string>(), f.at("fnv1a").get<std::string>()});
        if (p.input_files.back().path.empty()) throw std::runtime_error("an input file without a path");
      }
    }
    for (const auto& pt : p.points) {
      if (pt.size() != p.axes.size()) throw std::runtime_error("a point without one value per axis");
    }
    // What the sweep file's parser checks, checked again: a plan.json is a file on disk that
    // anyone may have edited, and the aggregation divides by samples and indexes by these names.
    if (p.samples < 1) throw std::runtime_error("samples must be >= 1");
    if (p.points.empty() || p.runs.empty()) throw std::runtime_error("a plan without points or runs");
    const auto metrics = p.metric_names();
    const auto known_metric = [&](const std::string& m) {
      if (std::find(metrics.begin(), metrics.end(), m) == metrics.end()) throw std::runtime_error("no metric '" + m + "'");
    };
    const auto grid_axis_path = [&](const std::string& path) {
      const auto a = std::find_if(p.axes.begin(), p.axes.end(), [&](const SweepAxis& x) { return x.path == path; });
      if (a == p.axes.end() || a->random()) throw std::runtime_error("no list or range axis '" + path + "'");
    };
    for (const auto& a : p.axes) {
      if (!a.random() && a.values.empty()) throw std::runtime_error("axis '" + a.path + "' has no values");
    }
    for (const auto& t : p.thresholds) known_metric(t.metric);
    for (const auto& m : p.maps) {
      known_metric(m.metric);
      grid_axis_path(m.x);
      grid_axis_path(m.y);
      for (const auto& [path, value] : m.slice) grid_axis_path(path);
    }
    known_metric(p.worst_by);
    return p;
  } catch (const json::exception& e) {
    throw std::runtime_error(origin + ": not a sweep plan (" + e.what() + ")");
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(origin + ": " + e.what());
  }
}

namespace {
// What a loaded campaign holds on the heap, roughly: its texts, schedules and runs, and a few kB
// for its plant and the rest (measured: robustness.yaml's points about 5 kB each).
std::size_t approx_bytes(const Campaign& c) {
  std::size_t bytes = 4096 + c.yaml_text.size() + c.plant_yaml_text.size() + c.description.size();
  for (const Schedule* s : {&c.reference_pa, &c.gap_rad}) {
    bytes += s->points().size() * sizeof(s->points().front()) + s->sines().size() * sizeof(s->sines().front());
  }
  return bytes + c.reversals_s.size() * sizeof(double) + c.runs.size() * sizeof(RunSpec);
}
}  // namespace

SweepPlan plan_sweep(const std::filesystem::path& sweep_file, long max_points,
                     const std::function<std::string(const std::string& name)>& checked_hash, const PlanCheckOptions& options) {
  std::string sweep_text;  // the file as parsed, for the plan's hash
  const Node root = Node::load_file(sweep_file, &sweep_text);
  root.allow_keys({"name", "description", "campaign", "runs", "seed", "samples", "axes", "thresholds", "maps", "worst_by"});
  SweepPlan plan;
  plan.name = root.text("name", sweep_file.stem().string());
  if (!cfg::plain_name(plan.name)) {
    (root.has("name") ? root.at("name") : root)
        .fail("'" + plan.name + "' is no plain name (letters, digits, '_', '-', '.'; it names the output folder)");
  }
  plan.description = root.text("description", "");

  // The base campaign, validated by its own loader, then as text and trees to edit.
  const auto campaign_file = root.resolve_path(root.text("campaign"));
  const Campaign base = [&] {
    try {
      return load_campaign(campaign_file);
    } catch (const cfg::Error& e) {
      root.at("campaign").fail(std::string("the base campaign: ") + e.what());
    }
  }();
  plan.campaign_yaml = base.yaml_text;
  plan.plant_yaml = base.plant_yaml_text;
  plan.campaign_dir = std::filesystem::absolute(campaign_file).parent_path();
  const YAML::Node campaign_tree = load_yaml(plan.campaign_yaml, campaign_file.string());
  const YAML::Node plant_tree = load_yaml(plan.plant_yaml, base.plant_file.string());

  std::vector<std::string> all_runs;
  for (const auto& r : base.runs) all_runs.push_back(r.name);
  if (auto runs = root.find("runs")) {
    runs->require(runs->is_sequence() && !runs->items().empty(), "needs a non-empty list of run names");
    std::set<std::string> wanted;
    for (const Node& r : runs->items()) {
      const std::string name = r.text();
      if (std::find(all_runs.begin(), all_runs.end(), name) == all_runs.end()) {
        const std::string hint = cfg::closest(name, all_runs);
        r.fail("the base campaign has no run '" + name + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)"));
      }
      r.require(wanted.insert(name).second, "listed twice");
    }
    for (const auto& r : all_runs)
      if (wanted.count(r)) plan.runs.push_back(r);  // in the campaign's order
  } else {
    plan.runs = all_runs;
  }

  const long long seed = root.integer("seed", 1);
  if (auto s = root.find("seed")) s->require(seed >= 0, "must be >= 0");
  plan.seed = static_cast<std::uint64_t>(seed);

  const Node axes = root.at("axes");
  axes.require(axes.is_sequence() && !axes.items().empty(), "needs a list of axes");
  std::set<std::string> seen;
  const std::string campaign_name = campaign_file.filename().string(), plant_name = base.plant_file.filename().string();
  // The value a (valid) axis path names, however it is spelled.
  const auto canonical_of = [](const std::string& path) {
    const auto p = parse_path(path);
    return (p->plant ? "plant" : "campaign") + describe(p->steps, p->steps.size());
  };
  for (const Node& a : axes.items()) {
    plan.axes.push_back(read_axis(a, campaign_tree, plant_tree, campaign_name, plant_name));
    a.at("path").require(seen.insert(canonical_of(plan.axes.back().path)).second, "two axes set the same value");
  }
  // An increment adds to a value an absolute axis set (or the campaign's own): one whose base is
  // itself an increment would depend on the order the increments are applied in, and two that
  // name each other (a cycle) ran with whatever that order made.
  for (std::size_t i = 0; i < plan.axes.size(); ++i) {
    if (plan.axes[i].relative_to.empty()) continue;
    const std::string base = canonical_of(plan.axes[i].relative_to);
    for (const SweepAxis& other : plan.axes) {
      if (other.relative_to.empty() || canonical_of(other.path) != base) continue;
      axes.items()[i]
          .at("relative_to")
          .fail("'" + plan.axes[i].relative_to + "' is itself an increment (relative to '" + other.relative_to +
                "'): an axis may be relative only to a value no other axis increments "
                "(a chain or cycle of increments has no order)");
    }
  }
  const bool random = std::any_of(plan.axes.begin(), plan.axes.end(), [](const SweepAxis& a) { return a.random(); });
  if (auto s = root.find("samples")) {
    s->require(random, "samples are draws of distribution axes (uniform, normal), and this sweep has none");
    s->require(s->integer() >= 1 && s->integer() <= max_points,
               "must be a whole number in [1, " + std::to_string(max_points) + "]");
    plan.samples = static_cast<long>(s->integer());
  } else if (random) {
    root.fail("missing required key 'samples' (draws per grid cell of the distribution axes)");
  }

  // The count as the product that makes it (in floating point: it may not fit a long), so the
  // user sees which axis to thin.
  std::string product;
  double points = static_cast<double>(plan.samples);
  for (const auto& a : plan.axes) {
    if (a.random()) continue;
    points *= static_cast<double>(a.values.size());
    product += (product.empty() ? "" : " x ") + std::to_string(a.values.size());
  }
  if (plan.samples > 1) product += (product.empty() ? "" : " x ") + std::to_string(plan.samples) + " samples";
  char count[32];
  std::snprintf(count, sizeof count, "%.4g", points);
  if (points > static_cast<double>(max_points))
    axes.fail(product + " = " + count + " points; a sweep has at most " + std::to_string(max_points));
  // Point p = cell * samples + sample; the cell's grid values with the last axis fastest.
  const long total = static_cast<long>(points);  // exact: a whole number of at most max_points
  plan.points.reserve(static_cast<std::size_t>(total));
  for (long p = 0; p < total; ++p) {
    std::vector<std::string> values(plan.axes.size());
    long cell = p / plan.samples;
    for (std::size_t i = plan.axes.size(); i-- > 0;) {
      const SweepAxis& a = plan.axes[i];
      if (a.random()) {
        values[i] = shortest(draw(a, plan.seed, p, i));
      } else {
        const long n = static_cast<long>(a.values.size());
        values[i] = a.values[static_cast<std::size_t>(cell % n)];
        cell /= n;
      }
    }
    plan.points.push_back(std::move(values));
  }

  const auto metrics = plan.metric_names();
  if (auto t = root.find("thresholds")) {
    for (const auto& [metric, bound] : t->entries()) {
      require_metric(bound, metric, metrics);
      bound.allow_keys({"min", "max"});
      SweepBound b{metric};
      if (bound.has("min")) b.min = bound.number("min");
      if (bound.has("max")) b.max = bound.number("max");
      bound.require(b.min || b.max, "needs min or max");
      if (b.min && b.max) bound.at("max").require(*b.max >= *b.min, "must be >= min");
      plan.thresholds.push_back(std::move(b));
    }
  }
  if (auto maps = root.find("maps")) {
    for (const Node& m : maps->items()) {
      m.allow_keys({"metric", "x", "y", "reduce", "slice", "min", "max"});
      SweepMap map{m.text("metric"), m.text("x"), m.text("y"), m.text("reduce", "mean")};
      read_map_bound(m, map);
      require_metric(m.at("metric"), map.metric, metrics);
      grid_axis(m.at("x"), map.x, plan.axes);
      grid_axis(m.at("y"), map.y, plan.axes);
      m.at("y").require(map.x != map.y, "x and y must be two different axes");
      if (auto r = m.find("reduce"))
        r->require(map.reduce == "mean" || map.reduce == "max" || map.reduce == "min", "must be mean, max or min");
      if (auto s = m.find("slice")) {
        for (const auto& [path, value] : s->entries()) {
          const SweepAxis& a = grid_axis(value, path, plan.axes);
          value.require(path != map.x && path != map.y, "the map's own x and y cannot be sliced");
          const std::string v = value.text();
          auto same = [&](const std::string& w) {
            if (w == v) return true;
            double x = 0, y = 0;
            const auto rx = std::from_chars(w.data(), w.data() + w.size(), x);
            const auto ry = std::from_chars(v.data(), v.data() + v.size(), y);
            return rx.ec == std::errc() && ry.ec == std::errc() && rx.ptr == w.data() + w.size() &&
                   ry.ptr == v.data() + v.size() && x == y;
          };
          const auto hit = std::find_if(a.values.begin(), a.values.end(), same);
          if (hit == a.values.end()) {
            std::string known;
            for (const auto& w : a.values) known += (known.empty() ? "" : ", ") + w;
            value.fail("'" + v + "' is not a value of this axis (" + known + ")");
          }
          map.slice.emplace_back(path, *hit);
        }
      }
      plan.maps.push_back(std::move(map));
    }
  }
  if (auto w = root.find("worst_by")) {
    plan.worst_by = w->text();
    require_metric(*w, plan.worst_by, metrics);
  } else {
    plan.worst_by = !plan.maps.empty()         ? plan.maps.front().metric
                    : !plan.thresholds.empty() ? plan.thresholds.front().metric
                                               : metrics.front();
  }

  std::uint64_t h = fnv1a(sweep_text);
  h = fnv1a(plan.campaign_yaml, h);
  h = fnv1a(plan.plant_yaml, h);
  // Files the campaign reads besides its YAML (a csv reference): a resumed sweep whose reference
  // file changed would mix rows of the old file with rows of the new one.
  for (const auto& f : base.data_files) h = fnv1a(read_text_file(f, "a file the base campaign reads"), h);
  plan.hash = hex16(h);
  if (checked_hash && checked_hash(plan.name) == plan.hash) return plan;

  // Every point's campaign through the loader before anything runs: a value it refuses (a
  // negative gap, a reference out of the plant's reach) stops the sweep here, naming the point.
  // On every hardware thread, each point once; the refused point of the lowest index is reported
  // (not the first one found), so the message is the same on every machine.
  // The files the points read are gathered on the way (an axis may name another csv reference).
  std::atomic<long> next{0}, first_bad{plan.size()}, checked{0};
  std::atomic<bool> cancelled{false};
  std::vector<std::string> why(static_cast<std::size_t>(plan.size()));
  std::mutex mutex;  // guards files and the progress line
  std::set<std::filesystem::path> files(base.data_files.begin(), base.data_files.end());
  auto kept = std::make_shared<std::vector<std::unique_ptr<const Campaign>>>(static_cast<std::size_t>(plan.size()));
  std::atomic<std::size_t> kept_bytes{0};
  std::optional<ProgressLine> progress_line;
  if (options.progress) {
    ProgressLine::Options po;
    po.delay_s = 1;  // a sweep of a few hundred points is checked in well under a second: no line
    progress_line.emplace("sweep " + plan.name + ": checking each point's campaign", po);
  }
  auto check = [&] {
    const PointMaker maker(plan);
    for (long p = next.fetch_add(1); p < plan.size() && p < first_bad.load(); p = next.fetch_add(1)) {
      if (options.cancel != nullptr && options.cancel->load(std::memory_order_relaxed)) {
        cancelled.store(true);
        return;
      }
      try {
        Campaign c = maker.campaign(p);
        if (!c.data_files.empty()) {
          std::lock_guard lock(mutex);
          files.insert(c.data_files.begin(), c.data_files.end());
        }
        std::vector<std::string> names;
        for (const auto& r : c.runs) names.push_back(r.name);
        if (names != plan.runs) throw cfg::Error("its runs are not the sweep's runs");
        // Kept for the run while the budget lasts (its own slot: no lock).
        const std::size_t bytes = approx_bytes(c);
        if (kept_bytes.fetch_add(bytes) + bytes <= kKeptCampaignBytes) {
          (*kept)[static_cast<std::size_t>(p)] = std::make_unique<const Campaign>(std::move(c));
        } else {
          kept_bytes.fetch_sub(bytes);
        }
      } catch (const cfg::Error& e) {
        why[static_cast<std::size_t>(p)] = e.what();
        for (long seen = first_bad.load(); p < seen && !first_bad.compare_exchange_weak(seen, p);) {}
      }
      const long n = checked.fetch_add(1) + 1;
      if (progress_line) {
        std::lock_guard lock(mutex);
        progress_line->update(static_cast<double>(n) / static_cast<double>(plan.size()),
                              [&] { return "(" + std::to_string(n) + "/" + std::to_string(plan.size()) + " points)"; });
      }
    }
  };
  std::vector<std::thread> threads;
  for (unsigned t = 1; t < std::max(1u, std::thread::hardware_concurrency()); ++t) threads.emplace_back(check);
  check();
  for (auto& t : threads) t.join();
  if (progress_line) progress_line->end();
  if (cancelled.load()) throw Cancelled("sweep " + plan.name + ": stopped while its points were checked");
  if (const long p = first_bad.load(); p < plan.size()) {
    std::string values;
    for (std::size_t i = 0; i < plan.axes.size(); ++i)
      values += (i ? ", " : "") + plan.axes[i].path + " = " + plan.points[static_cast<std::size_t>(p)][i];
    axes.fail("point " + std::to_string(p) + " (" + values + "): " + why[static_cast<std::size_t>(p)]);
  }
  for (const auto& f : files) plan.input_files.push_back({std::filesystem::absolute(f), content_hash(f)});
  plan.checked_campaigns = std::move(kept);
  return plan;
}

void check_input_files(const SweepPlan& plan, const std::filesystem::path& dir) {
  for (const auto& f : plan.input_files) {
    std::string now;
    try {
      now = content_hash(f.path);
    } catch (const std::exception& e) {
      now = e.what();
    }
    if (now != f.hash) {
      throw std::runtime_error(f.path.string() + ": a file the sweep's points read has changed since " + dir.string() +
                               " was planned (or cannot be read now), and its rows were made with the old contents. Put it "
                               "back, use another --out, or remove " +
                               dir.string() + " to start afresh");
    }
  }
}

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
