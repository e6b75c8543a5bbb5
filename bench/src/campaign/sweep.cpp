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
#include "sweep_paths.hpp"
#include "hil/bench/rt/safety.hpp"
#include "hil/config.hpp"
#include "hil/parallel_for.hpp"
#include "hil/plant/rng.hpp"
#include "hil/progress_line.hpp"
#include "hil/text_file.hpp"
#include "sweep_words.hpp"

namespace hil::bench {
namespace {

using cfg::Node;
using json = nlohmann::json;

using namespace sweep_detail;

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

}  // namespace

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
  std::atomic<long> first_bad{plan.size()}, checked{0};
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
  // Each point once on every core (hil/parallel_for.hpp), a PointMaker per thread; the handing
  // out stops at a cancel and past the lowest refused point.
  hil::parallel_for(
      static_cast<std::size_t>(plan.size()), hil::worker_threads(static_cast<std::size_t>(plan.size())),
      [&plan] { return PointMaker(plan); },
      [&](const PointMaker& maker, std::size_t i) {
        const long p = static_cast<long>(i);
        if (p >= first_bad.load()) return false;
        if (options.cancel != nullptr && options.cancel->load(std::memory_order_relaxed)) {
          cancelled.store(true);
          return false;
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
            (*kept)[i] = std::make_unique<const Campaign>(std::move(c));
          } else {
            kept_bytes.fetch_sub(bytes);
          }
        } catch (const cfg::Error& e) {
          why[i] = e.what();
          for (long seen = first_bad.load(); p < seen && !first_bad.compare_exchange_weak(seen, p);) {}
        }
        const long n = checked.fetch_add(1) + 1;
        if (progress_line) {
          std::lock_guard lock(mutex);
          progress_line->update(static_cast<double>(n) / static_cast<double>(plan.size()),
                                [&] { return "(" + std::to_string(n) + "/" + std::to_string(plan.size()) + " points)"; });
        }
        return true;
      });
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

}  // namespace hil::bench
