// A sweep's plan as sweep.json keeps it (SweepPlan::to_json, from_json) and its metric names.
#include <algorithm>
#include <string_view>

#include "hil/bench/campaign/sweep.hpp"
#include "hil/config.hpp"
#include "sweep_words.hpp"

namespace hil::bench {

using json = nlohmann::json;

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

}  // namespace hil::bench
