#include "hil/bench/campaign/campaign.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <stdexcept>

#include "hil/config.hpp"
#include "hil/config_files.hpp"
#include "hil/csv_reader.hpp"
#include "hil/plant/registry.hpp"
#include "hil/plant/rng.hpp"
#include "hil/physics.hpp"
#include "hil/telemetry_schema.hpp"
#include "hil/units.hpp"

namespace hil::bench {
namespace {

using cfg::Node;
using units::deg_to_rad;
using units::kPaPerKpa;
using units::mpa_to_pa;

double param_of(const plant::Plant& plant, std::string_view kind, std::string_view key) {
  const plant::Effect* e = plant.find(kind);
  if (e == nullptr) throw std::invalid_argument("the plant has no '" + std::string(kind) + "' block");
  for (const auto& p : e->params())
    if (p.key == key) return p.value;
  throw std::invalid_argument(std::string(kind) + " has no parameter '" + std::string(key) + "'");
}

// Where each level of a schedule came from, so an out-of-range level names its YAML item.
struct Origin {
  double value;
  Node node;
};

// Builds a piecewise-linear schedule from a list of profile items in time order.
class ScheduleBuilder {
 public:
  ScheduleBuilder(double initial, double duration_s, Node initial_node, double unit)
      : schedule_(initial), level_(initial), duration_s_(duration_s), unit_(unit) {
    origins_.push_back({initial, std::move(initial_node)});
  }
  // An item starting at t_s: must not overlap the previous one and must lie inside the run.
  void starts(const Node& item, double t_s) {
    item.require(t_s >= busy_until_ - 1e-12, "starts before the previous item ends (" + std::to_string(busy_until_) + " s)");
    item.require(t_s <= duration_s_, "starts after the campaign ends (" + std::to_string(duration_s_) + " s)");
    schedule_.add(t_s, level_);
  }
  void go(const Node& where, double t_s, double level) {
    schedule_.add(t_s, level);
    level_ = level;
    busy_until_ = std::max(busy_until_, t_s);
    origins_.push_back({level, where});
  }
  void sine(const SineOverlay& s, const Node& where) {
    schedule_.add_sine(s);
    origins_.push_back({level_ + std::abs(s.amplitude), where});
    origins_.push_back({level_ - std::abs(s.amplitude), where});
  }
  double level() const { return level_; }
  double unit() const { return unit_; }
  const std::vector<Origin>& origins() const { return origins_; }
  Schedule take() { return std::move(schedule_); }

 private:
  Schedule schedule_;
  double level_;
  double busy_until_ = 0;
  double duration_s_;
  double unit_;  // SI per config unit (Pa per MPa, rad per deg)
  std::vector<Origin> origins_;
};

std::pair<double, double> range_of(const Node& n, std::string_view key) {
  const Node r = n.at(key);
  const auto v = r.numbers();
  r.require(v.size() == 2 && v[0] > 0 && v[1] >= v[0], "needs [min, max] with 0 < min <= max");
  return {v[0], v[1]};
}

double uniform(plant::Rng& rng, std::pair<double, double> r) { return r.first + (r.second - r.first) * rng.uniform(); }

// Reference items: step, ramp, square, points, sine, csv, random. Values in MPa.
void add_reference_item(ScheduleBuilder& b, std::vector<std::filesystem::path>& data_files, const Node& item,
                        const std::string& type, const Node& body, double duration_s, std::uint64_t campaign_seed) {
  const double u = b.unit();
  if (type == "step") {
    body.allow_keys({"at_s", "to_mpa"});
    const double at = body.number("at_s");
    b.starts(body.at("at_s"), at);
    b.go(body.at("to_mpa"), at, body.number("to_mpa") * u);
  } else if (type == "ramp") {
    body.allow_keys({"from_s", "to_s", "to_mpa"});
    const double from = body.number("from_s"), to = body.number("to_s");
    body.at("to_s").require(to > from, "must be after from_s");
    b.starts(body.at("from_s"), from);
    b.go(body.at("to_mpa"), to, body.number("to_mpa") * u);
  } else if (type == "square") {
    body.allow_keys({"from_s", "to_s", "half_period_s", "low_mpa", "high_mpa", "first"});
    const double from = body.number("from_s"), to = body.number("to_s", duration_s);
    const double half = body.number("half_period_s");
    body.at("half_period_s").require(half > 0, "must be > 0");
    const double low = body.number("low_mpa") * u, high = body.number("high_mpa") * u;
    body.at("high_mpa").require(high > low, "must be above low_mpa");
    const std::string first = body.text("first", std::abs(b.level() - low) < std::abs(b.level() - high) ? "high" : "low");
    if (auto f = body.find("first")) f->require(first == "high" || first == "low", "must be high or low");
    b.starts(body.at("from_s"), from);
    bool high_now = first == "high";
    for (double t = from; t < to - 1e-9; t += half, high_now = !high_now) {
      b.go(body.at(high_now ? "high_mpa" : "low_mpa"), t, b.level());
      b.go(body.at(high_now ? "high_mpa" : "low_mpa"), t, high_now ? high : low);
    }
  } else if (type == "points") {
    body.allow_keys({"t_s", "p_mpa"});
    const auto t = body.at("t_s").numbers(), p = body.at("p_mpa").numbers();
    body.at("p_mpa").require(p.size() == t.size() && !t.empty(), "needs one pressure per time");
    for (std::size_t i = 1; i < t.size(); ++i) body.at("t_s").require(t[i] > t[i - 1], "times must increase");
    b.starts(body.at("t_s"), t[0]);
    for (std::size_t i = 0; i < t.size(); ++i) b.go(body.at("p_mpa"), t[i], p[i] * u);
  } else if (type == "sine") {
    body.allow_keys({"from_s", "to_s", "amplitude_mpa", "period_s"});
    const double period = body.number("period_s");
    body.at("period_s").require(period > 0, "must be > 0");
    b.sine({body.number("from_s", 0.0), body.number("to_s", duration_s), body.number("amplitude_mpa") * u, period},
           body.at("amplitude_mpa"));
  } else if (type == "csv") {
    body.allow_keys({"file", "column", "time_column"});
    const auto file = body.resolve_path(body.text("file"));
    data_files.push_back(file);
    // By default a telemetry file's reference and time columns (hil/telemetry_schema.hpp).
    const std::string col = body.text("column", telemetry::name(telemetry::Col::p_ref_mpa)),
                      tcol = body.text("time_column", telemetry::name(telemetry::Col::t_s));
    CsvChunk data;
    // The campaign is made of this file too: a cache of it (GET /api/campaigns) must see it change.
    cfg::ReadFiles::note(file);
    try {
      data = read_csv(file, {{tcol, col}, {}, tcol});
    } catch (const CsvError& e) {
      body.at("file").fail(e.what());
    }
    body.at("file").require(data.rows() > 0, "the file has no rows");
    b.starts(body.at("file"), data.values[0][0]);
    for (std::size_t i = 0; i < data.rows(); ++i) b.go(body.at("file"), data.values[0][i], data.values[1][i] * u);
  } else if (type == "random") {
    body.allow_keys({"seed", "from_s", "to_s", "min_mpa", "max_mpa", "dwell_s", "ramp_probability", "ramp_s", "min_change_mpa",
                     "directions"});
    plant::Rng rng(static_cast<std::uint64_t>(body.integer("seed", static_cast<long long>(campaign_seed) + 7919)));
    const double from = body.number("from_s", 0.0), to = body.number("to_s", duration_s);
    const double lo = body.number("min_mpa") * u, hi = body.number("max_mpa") * u;
    body.at("max_mpa").require(hi > lo, "must be above min_mpa");
    const double min_change = body.number("min_change_mpa", 0.1) * u;
    body.require(min_change < hi - lo, "min_change_mpa must be below max_mpa - min_mpa");
    const auto dwell = range_of(body, "dwell_s");
    const double ramp_p = body.number("ramp_probability", 0.3);
    body.require(ramp_p >= 0 && ramp_p <= 1, "ramp_probability must be in [0, 1]");
    const auto ramp_s = body.has("ramp_s") ? range_of(body, "ramp_s") : std::pair{0.2, 1.0};
    const std::string directions = body.text("directions", "random");
    if (auto d = body.find("directions"))
      d->require(directions == "random" || directions == "alternate", "must be random or alternate");
    body.require(directions == "random" || min_change < (hi - lo) / 2,
                 "alternating directions need min_change_mpa below half of max_mpa - min_mpa");
    b.starts(body, from);
    double t = from;
    int dir = b.level() < (lo + hi) / 2 ? 1 : -1;
    const bool alternate = directions == "alternate";
    // Whether a level of [lo, hi) lies at least min_change from `level` (up: want > 0, down: < 0,
    // either: 0). Levels are only drawn so that the move after them stays possible; a start level
    // outside [lo, hi] (or, for random directions, in the middle of a narrow range) could leave
    // none, and the draw below would never end.
    auto can_move = [&](double level, int want) {
      const bool up = hi - level > min_change, down = level - lo >= min_change;
      return want > 0 ? up : want < 0 ? down : (up || down);
    };
    body.require(can_move(b.level(), alternate ? dir : 0),
                 "no level within [min_mpa, max_mpa] is min_change_mpa away from the reference at from_s (" +
                     std::to_string(b.level() / u) + " MPa)");
    while (true) {
      // A level at least min_change away; alternating: on the other side of the last move.
      double next = b.level();
      while (std::abs(next - b.level()) < min_change || (alternate && dir * (next - b.level()) < 0) ||
             !can_move(next, alternate ? -dir : 0)) {
        next = lo + (hi - lo) * rng.uniform();
      }
      dir = -dir;
      const double ramp = rng.uniform() < ramp_p ? uniform(rng, ramp_s) : 0.0;
      if (t + ramp >= to) break;
      b.go(body, t, b.level());
      b.go(body, t + ramp, next);
      t += ramp + uniform(rng, dwell);
    }
  } else {
    item.fail("unknown profile item '" + type + "'; known: step, ramp, square, points, sine, csv, random");
  }
}

// Gap program items: step, drift, random_drift. Values in degrees.
void add_gap_item(ScheduleBuilder& b, const Node& item, const std::string& type, const Node& body, double duration_s,
                  std::uint64_t campaign_seed) {
  const double u = b.unit();
  auto gap_at = [&](const Node& n, std::string_view key) {
    const Node v = n.at(key);
    v.require(v.number() >= 0, "a gap cannot be negative");
    return v.number() * u;
  };
  if (type == "step") {
    body.allow_keys({"at_s", "to_deg"});
    const double at = body.number("at_s");
    b.starts(body.at("at_s"), at);
    b.go(body.at("to_deg"), at, gap_at(body, "to_deg"));
  } else if (type == "drift") {
    body.allow_keys({"from_s", "to_s", "to_deg"});
    const double from = body.number("from_s"), to = body.number("to_s");
    body.at("to_s").require(to > from, "must be after from_s");
    b.starts(body.at("from_s"), from);
    b.go(body.at("to_deg"), to, gap_at(body, "to_deg"));
  } else if (type == "random_drift") {
    body.allow_keys({"seed", "from_s", "to_s", "min_deg", "max_deg", "segment_s"});
    plant::Rng rng(static_cast<std::uint64_t>(body.integer("seed", static_cast<long long>(campaign_seed) + 104729)));
    const double from = body.number("from_s", 0.0), to = body.number("to_s", duration_s);
    const double lo = gap_at(body, "min_deg"), hi = gap_at(body, "max_deg");
    body.at("max_deg").require(hi > lo, "must be above min_deg");
    const auto seg = range_of(body, "segment_s");
    b.starts(body, from);
    for (double t = from; t < to;) {
      const double end = std::min(t + uniform(rng, seg), to);
      b.go(body, end, lo + (hi - lo) * rng.uniform());
      t = end;
    }
  } else {
    item.fail("unknown gap change '" + type + "'; known: step, drift, random_drift");
  }
}

template <class AddItem>
void add_items(ScheduleBuilder& b, const std::optional<Node>& list, AddItem add) {
  if (!list) return;
  for (const Node& item : list->items()) {
    const auto entries = item.entries();
    item.require(entries.size() == 1, "each item is one mapping like '- step: {at_s: 2.5, to_mpa: 1.5}'");
    add(b, item, entries[0].first, entries[0].second);
  }
}

ctl::Compensation compensation_of(const Node& n) {
  const std::string s = n.text();
  n.require(s == "none" || s == "constant" || s == "adaptive", "must be none, constant or adaptive");
  return s == "none" ? ctl::Compensation::none : s == "constant" ? ctl::Compensation::constant : ctl::Compensation::adaptive;
}

// The controller block's keys: its own, and one block of parameters per registered compensator,
// named after it (`robust: {detect_sigmas: 4}`): a campaign may set several, each run uses its
// compensator's. `observer:` is the older name of `compensator:`.
std::vector<std::string> controller_keys() {
  std::vector<std::string> keys = {"compensator",     "observer",      "compensation", "known_gap_deg",
                                   "initial_gap_deg", "damping_ratio", "use_encoder",  "traverse_boost"};
  for (auto& name : ctl::compensator_names()) keys.push_back(std::move(name));
  return keys;
}

// Parameter values per compensator name, in its specs' order and units.
using CompensatorParams = std::map<std::string, std::vector<double>, std::less<>>;

// Applies controller keys of `n` (campaign defaults or one run) onto `p` and `params`.
void read_controller(const Node& n, ctl::ControllerParams& p, CompensatorParams& params) {
  n.require(!(n.has("compensator") && n.has("observer")), "give 'compensator' or its older name 'observer', not both");
  for (const char* key : {"compensator", "observer"}) {
    if (auto v = n.find(key)) {
      std::string known;
      for (const auto& name : ctl::compensator_names()) known += (known.empty() ? "" : ", ") + name;
      v->require(ctl::find_compensator(v->text()) != nullptr, "must be a registered compensator: " + known);
      p.compensator = v->text();
    }
  }
  for (const auto& name : ctl::compensator_names()) {
    if (auto block = n.find(name)) {
      const auto& specs = ctl::find_compensator(name)->specs;
      auto [it, added] = params.try_emplace(name, param_defaults(specs));
      apply_params(*block, specs, it->second);
    }
  }
  if (auto v = n.find("compensation")) p.compensation = compensation_of(*v);
  if (auto v = n.find("known_gap_deg")) {
    v->require(v->number() >= 0, "a gap cannot be negative");
    p.gap_known_rad = deg_to_rad(v->number());
  }
  if (auto v = n.find("initial_gap_deg")) {
    v->require(v->number() >= 0, "a gap cannot be negative");
    p.gap_initial_rad = deg_to_rad(v->number());
  }
  if (auto v = n.find("damping_ratio")) {
    v->require(v->number() > 0 && v->number() < 5, "must be in (0, 5)");
    p.damping_ratio = v->number();
  }
  if (auto v = n.find("use_encoder")) p.use_encoder = v->boolean();
  if (auto v = n.find("traverse_boost")) {
    v->require(v->number() >= 0 && v->number() <= 5, "must be in [0, 5] (a fraction of the jump)");
    p.traverse_boost = v->number();
  }
}

// The longest campaign a run may last: a week at the bench, also what bounds the memory of a
// random profile's items and of a simulation's report.
constexpr double kMaxDurationS = 7 * 86400.0;
constexpr double kMaxPeriods = kMaxDurationS * 1000;  // 7 days at 1 kHz

// A name that becomes a folder: plain, and never "." or ".." (they would name the parent).
void require_plain_name(const Node& where, const std::string& name) {
  where.require(
      cfg::plain_name(name),
      "must be a plain name (letters, digits, '_', '-', '.'; not starting with '.'; at most 100 characters), it names a folder");
}

Campaign load(const Node& root, const std::filesystem::path& file, const std::string& text,
              const std::filesystem::path& plants_root, const Node* plant_root = nullptr, const std::string& plant_text = {}) {
  root.allow_keys({"name", "description", "plant", "duration_s", "period_ms", "seed", "sensor_noise_kpa", "reference", "gap",
                   "controller", "runs", "checks"});
  Campaign c;
  c.file = file;
  c.yaml_text = text;
  c.name = root.text("name", file.stem().string());
  if (root.has("name")) {
    require_plain_name(root.at("name"), c.name);
  } else if (!cfg::plain_name(c.name)) {
    root.fail("the file name '" + c.name + "' is no plain name; give the campaign a 'name:'");
  }
  c.description = root.text("description", "");

  c.plant_file = plant_root != nullptr ? plant_root->file() : root.resolve_path(root.text("plant"));
  if (!plants_root.empty()) {
    // A campaign from outside (posted over the API) may read plant files of this bench only:
    // never /etc/shadow, whose first line a YAML error would quote back.
    std::error_code ec;
    const auto real = std::filesystem::weakly_canonical(c.plant_file, ec);
    const auto root_real = std::filesystem::weakly_canonical(plants_root, ec);
    const auto rel = real.lexically_relative(root_real);
    if (ec || rel.empty() || *rel.begin() == "..") {
      root.at("plant").fail("a posted campaign may only name a plant file inside " + plants_root.string());
    }
  }
  plant::Plant truth = [&] {
    try {
      if (plant_root != nullptr) {
        c.plant_yaml_text = plant_text;
        return plant::Plant::from_yaml(*plant_root);
      }
      return plant::Plant::from_yaml(Node::load_file(c.plant_file, &c.plant_yaml_text));
    } catch (const cfg::Error& e) {
      root.at("plant").fail(std::string("in the plant file: ") + e.what());
    }
  }();

  c.duration_s = root.number("duration_s");
  root.at("duration_s").require(c.duration_s > 0 && c.duration_s <= kMaxDurationS, "must be > 0 and at most 604800 s (7 days)");
  const double period_ms = root.number("period_ms", 1.0);
  if (auto p = root.find("period_ms"))
    p->require(period_ms >= kMinPeriodMs && period_ms <= kMaxPeriodMs,
               "the control period dT must be 0.01..1000 ms (100 kHz to 1 Hz)");
  c.period_s = period_ms * 1e-3;
  // Loading walks the reference once a period (its reversals): a week at 1 ns a period would
  // hold a server's request thread for hours, so the count is bounded as well as each number.
  if (c.duration_s / c.period_s > kMaxPeriods) {
    (root.has("period_ms") ? root.at("period_ms") : root.at("duration_s"))
        .fail("duration_s / dT is " + std::to_string(std::llround(c.duration_s / c.period_s)) +
              " periods; at most 604800000 (7 days at 1 kHz): a longer period or a shorter campaign");
  }
  const long long seed = root.integer("seed", 1);
  if (root.has("seed")) root.at("seed").require(seed >= 0, "must be >= 0");
  c.seed = static_cast<std::uint64_t>(seed);

  if (auto noise = root.find("sensor_noise_kpa")) {
    noise->require(noise->number() >= 0, "noise cannot be negative");
    const std::vector<double> v{noise->number()};
    const plant::Effect* sensor = truth.find("pressure_sensor");
    try {
      truth = truth.with(sensor ? sensor->with_params(v)
                                : plant::find_effect("pressure_sensor")
                                      ->from_yaml(Node::load_string("noise_rms_kpa: " + noise->text(), "sensor_noise_kpa")));
    } catch (const std::invalid_argument& e) {  // the effect's own range check, e.g. above 10000 kPa
      noise->fail(e.what());
    }
  }
  c.sensor_noise_rms_pa = truth.find("pressure_sensor") ? truth.find("pressure_sensor")->params().at(0).value * kPaPerKpa : 0;

  // Reference profile, in MPa, checked against what the plant can reach.
  const Node ref = root.at("reference");
  ref.allow_keys({"initial_mpa", "profile"});
  {
    ScheduleBuilder b(ref.number("initial_mpa") * units::kPaPerMpa, c.duration_s, ref.at("initial_mpa"), units::kPaPerMpa);
    add_items(b, ref.find("profile"), [&](ScheduleBuilder& sb, const Node& item, const std::string& type, const Node& body) {
      add_reference_item(sb, c.data_files, item, type, body, c.duration_s, c.seed);
    });
    const auto [lo, hi] = truth.pressure_range_pa();
    for (const auto& o : b.origins()) {
      if (o.value >= lo && o.value <= hi) continue;
      char msg[200];
      std::snprintf(msg, sizeof msg, "reference %.4g MPa is outside what the plant reaches (%.4g to %.4g MPa)",
                    units::pa_to_mpa(o.value), units::pa_to_mpa(lo), units::pa_to_mpa(hi));
      o.node.fail(msg);
    }
    c.reference_pa = b.take();
  }
  c.reversals_s = reversal_times(c.reference_pa, c.duration_s, c.period_s, 1e3);
  c.reference_moves = move_count(c.reference_pa, c.duration_s, c.period_s);

  // Programmed gap, in degrees; default: the plant's own.
  const double plant_gap_deg = param_of(truth, "backlash", "gap_deg");
  if (auto gap = root.find("gap")) {
    gap->allow_keys({"initial_deg", "changes"});
    const double initial = gap->number("initial_deg", plant_gap_deg);
    if (auto n = gap->find("initial_deg")) n->require(initial >= 0, "a gap cannot be negative");
    ScheduleBuilder b(deg_to_rad(initial), c.duration_s, gap->has("initial_deg") ? gap->at("initial_deg") : *gap,
                      units::kRadPerDeg);
    add_items(b, gap->find("changes"), [&](ScheduleBuilder& sb, const Node& item, const std::string& type, const Node& body) {
      add_gap_item(sb, item, type, body, c.duration_s, c.seed);
    });
    const plant::Effect* backlash = truth.find("backlash");
    for (const auto& spec : backlash->specs()) {
      if (spec.key != "gap_deg") continue;
      for (const auto& o : b.origins()) {
        if (o.value <= deg_to_rad(spec.hi)) continue;
        char msg[160];
        std::snprintf(msg, sizeof msg, "a gap of %.4g deg is more than the backlash effect allows (%.4g deg)",
                      units::rad_to_deg(o.value), spec.hi);
        o.node.fail(msg);
      }
    }
    c.gap_rad = b.take();
  } else {
    c.gap_rad = Schedule(deg_to_rad(plant_gap_deg));
  }

  // Controller defaults from the plant (the designer's nominal model) and the campaign.
  ctl::ControllerParams base;
  try {
    base.chamber = chamber_model_of(truth);
  } catch (const std::invalid_argument& e) {
    root.at("plant").fail(std::string("the controller's model: ") + e.what());
  }
  base.period_s = c.period_s;
  base.volume_initial_m3 = param_of(truth, "gas_generator", "free_volume_l") * units::kM3PerL;
  base.motor.time_constant_s = param_of(truth, "motor_servo", "time_constant_s");
  base.motor.rate_limit_rad_s = deg_to_rad(param_of(truth, "motor_servo", "rate_limit_deg_s"));
  double gap_max_rad = std::max(deg_to_rad(6.0), c.gap_rad.initial());
  for (const auto& p : c.gap_rad.points()) gap_max_rad = std::max(gap_max_rad, p.value);
  base.cmd_min_rad = deg_to_rad(param_of(truth, "backlash", "valve_min_deg")) - gap_max_rad;
  base.cmd_max_rad = deg_to_rad(param_of(truth, "backlash", "valve_max_deg")) + gap_max_rad;
  base.gap_known_rad = c.gap_rad.initial();
  const std::vector<std::string> keys_of_controller = controller_keys();
  CompensatorParams base_params;
  if (auto ctl = root.find("controller")) {
    ctl->allow_keys(keys_of_controller);
    read_controller(*ctl, base, base_params);
  }

  const Node runs = root.at("runs");
  for (const Node& run : runs.items()) {
    std::vector<std::string> keys = keys_of_controller;
    keys.insert(keys.end(), {"name", "description"});
    run.allow_keys(keys);
    RunSpec spec;
    spec.name = run.text("name");
    require_plain_name(run.at("name"), spec.name);
    for (const auto& other : c.runs) run.at("name").require(other.name != spec.name, "two runs have this name");
    spec.controller = base;
    CompensatorParams params = base_params;
    read_controller(run, spec.controller, params);
    if (auto it = params.find(spec.controller.compensator); it != params.end()) spec.controller.compensator_params = it->second;
    run.require(run.has("compensation") || (root.has("controller") && root.at("controller").has("compensation")),
                "missing required key 'compensation' (none, constant or adaptive)");
    try {
      spec.controller.validate();
    } catch (const std::invalid_argument& e) {
      run.fail(e.what());
    }
    c.runs.push_back(std::move(spec));
  }
  runs.require(!c.runs.empty(), "needs at least one run");
  if (auto checks = root.find("checks")) {
    std::vector<std::string> names;
    for (const auto& r : c.runs) names.push_back(r.name);
    c.checks = parse_checks(*checks, names);
  }
  c.plant = std::make_shared<const plant::Plant>(std::move(truth));
  return c;
}

}  // namespace

ctl::ChamberModel chamber_model_of(const plant::Plant& plant) {
  ctl::ChamberModel m;
  m.propellant_density_kg_m3 = param_of(plant, "gas_generator", "propellant_density_kg_m3");
  m.pressure_exponent = param_of(plant, "gas_generator", "pressure_exponent");
  m.burn_coeff_si = physics::burn_coeff_si(param_of(plant, "gas_generator", "burn_rate_mm_s_at_1mpa"), m.pressure_exponent);
  m.burning_area_m2 = param_of(plant, "gas_generator", "burning_area_m2");
  m.cstar_m_s = param_of(plant, "gas_generator", "cstar_m_s");
  m.rtc_m2_s2 = param_of(plant, "gas_generator", "rtc_m2_s2");
  m.volume_growth = param_of(plant, "gas_generator", "volume_growth");
  const plant::Effect* map = plant.find("throat_map");
  if (map == nullptr) throw std::invalid_argument("the plant has no 'throat_map' block");
  const auto tables = map->tables();
  const auto& angle = tables.at(0).values;
  const auto& area = tables.at(1).values;
  if (angle.size() > ctl::ChamberModel::kMaxMapPoints) throw std::invalid_argument("the throat map has more than 16 points");
  m.map_points = angle.size();
  for (std::size_t i = 0; i < angle.size(); ++i) {
    m.map_angle_rad[i] = deg_to_rad(angle[i]);
    m.map_area_m2[i] = area[i] * units::kM2PerMm2;
  }
  m.validate();
  return m;
}

Campaign with_sensor_noise(Campaign c, double noise_rms_kpa) {
  if (!(noise_rms_kpa >= 0)) throw std::invalid_argument("sensor noise must be >= 0 kPa");
  const std::vector<double> v{noise_rms_kpa};
  const plant::Effect* sensor = c.plant->find("pressure_sensor");
  auto effect = sensor ? sensor->with_params(v)
                       : plant::find_effect("pressure_sensor")
                             ->from_yaml(Node::load_string("noise_rms_kpa: " + std::to_string(noise_rms_kpa), "noise"));
  c.plant = std::make_shared<const plant::Plant>(c.plant->with(effect));
  c.sensor_noise_rms_pa = noise_rms_kpa * kPaPerKpa;
  return c;
}

Campaign load_campaign(const std::filesystem::path& file) {
  std::string text;
  const Node root = Node::load_file(file, &text);
  return load(root, file, text, {});
}

Campaign load_campaign_text(const std::string& yaml, const std::string& origin, const std::filesystem::path& base_dir,
                            const std::filesystem::path& plants_root) {
  const std::filesystem::path pseudo = base_dir / origin;
  const Node root = Node::load_string(yaml, pseudo.string());
  return load(root, pseudo, yaml, plants_root);
}

Campaign load_campaign_text(const std::string& yaml, const std::string& origin, const std::filesystem::path& base_dir,
                            const std::string& plant_yaml, const std::filesystem::path& plant_origin) {
  const std::filesystem::path pseudo = base_dir / origin;
  const Node root = Node::load_string(yaml, pseudo.string());
  const Node plant_root = Node::load_string(plant_yaml, plant_origin.string());
  return load(root, pseudo, yaml, {}, &plant_root, plant_yaml);
}

}  // namespace hil::bench
