#include "hil/plant/plant.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>

#include "hil/config.hpp"
#include "hil/plant/registry.hpp"
#include "hil/units.hpp"

namespace hil::plant {
namespace {

constexpr Stage kRequired[] = {Stage::motor, Stage::transmission, Stage::throat, Stage::chamber};

std::string_view stage_name(Stage s) {
  switch (s) {
    case Stage::motor: return "motor (e.g. motor_servo)";
    case Stage::transmission: return "transmission (e.g. backlash)";
    case Stage::throat: return "throat (e.g. throat_map)";
    case Stage::chamber: return "chamber (e.g. gas_generator)";
    default: return "other";
  }
}

// The settle bisection searches valve angles in this window; throat maps clamp beyond their table.
constexpr double kSearchLoRad = -1.0;
constexpr double kSearchHiRad = 1.0;

}  // namespace

Plant::Plant(std::vector<std::shared_ptr<const Effect>> effects) : effects_(std::move(effects)) {
  std::stable_sort(effects_.begin(), effects_.end(), [](const auto& a, const auto& b) { return a->stage() < b->stage(); });
  for (std::size_t i = 0; i < effects_.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      if (effects_[i]->kind() == effects_[j]->kind()) {
        throw std::invalid_argument("plant: effect '" + std::string(effects_[i]->kind()) + "' appears twice");
      }
    }
  }
  // Each required stage needs an effect that makes its signal; more effects at one stage run in
  // the order given and modify it (a user's stiction after the backlash, which diagnose attaches
  // last: analysis/README.md, user effects).
  for (Stage need : kRequired) {
    const auto n = std::count_if(effects_.begin(), effects_.end(), [&](const auto& e) { return e->stage() == need; });
    if (n < 1) throw std::invalid_argument("plant: needs a " + std::string(stage_name(need)) + " effect, has none");
  }
  first_sensor_ = effects_.size();
  for (std::size_t i = 0; i < effects_.size(); ++i) {
    offsets_.push_back(state_size_);
    chain_.push_back({effects_[i].get(), state_size_, effects_[i]->state_size()});
    state_size_ += effects_[i]->state_size();
    if (first_sensor_ == effects_.size() && effects_[i]->stage() > Stage::chamber) first_sensor_ = i;
  }
}

Plant Plant::from_yaml(const cfg::Node& root) {
  root.allow_keys({"effects", "description"});
  const cfg::Node block = root.at("effects");
  std::vector<std::shared_ptr<const Effect>> effects;
  for (const auto& [name, node] : block.entries()) {
    const EffectInfo* info = find_effect(name);
    if (info == nullptr) {
      const std::string hint = cfg::closest(name, effect_names());
      std::string known;
      for (const auto& n : effect_names()) known += (known.empty() ? "" : ", ") + n;
      node.fail("unknown effect '" + name + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)") + "; known effects: " +
                known + " (an effect added to the sources is known once hilbench is rebuilt: " + "scripts/build.sh hilbench)");
    }
    effects.push_back(info->from_yaml(node));
  }
  try {
    Plant plant(std::move(effects));
    // Parameters each in range can still give a chamber with no steady state (a burning area of
    // 1 m^2 or a c* of 1e5 m/s: the equilibrium overflows); said here, with the file, rather than
    // as "-nan to -nan MPa" when a run or a replay settles it.
    const auto [p_low_pa, p_high_pa] = plant.pressure_range_pa();
    if (!std::isfinite(p_low_pa) || !std::isfinite(p_high_pa)) {
      block.fail("these effects give the chamber no finite steady pressure with the valve fully open or closed (" +
                 std::to_string(units::pa_to_mpa(p_low_pa)) + " to " + std::to_string(units::pa_to_mpa(p_high_pa)) +
                 " MPa); check the gas generator's parameters against each other");
    }
    return plant;
  } catch (const std::invalid_argument& e) {
    block.fail(e.what());
  }
}

Plant Plant::load(const std::filesystem::path& file) { return from_yaml(cfg::Node::load_file(file)); }

PlantState Plant::make_state(std::uint64_t seed) const {
  PlantState st{std::vector<double>(state_size_, 0.0), Rng(seed), Signals{}};
  return st;
}

void Plant::step(PlantState& st, const PlantInputs& in, double dt_s) const noexcept {
  Signals& s = st.s;
  s.t_s += dt_s;  // effects produce the signals at the end of the step
  s.theta_cmd_rad = in.theta_cmd_rad;
  s.theta_motor_meas_rad = in.theta_motor_meas_rad;
  s.gap_rad = in.gap_rad;
  double* x = st.x.data();
  const Link* link = chain_.data();
  const Link* const sensors = link + first_sensor_;
  const Link* const end = link + chain_.size();
  for (; link != sensors; ++link) link->effect->step({x + link->offset, link->size}, s, dt_s, st.rng);
  s.p_meas_pa = s.p_chamber_pa;
  for (; link != end; ++link) link->effect->step({x + link->offset, link->size}, s, dt_s, st.rng);
}

double Plant::settle_chain(PlantState& st, double cmd_rad, double valve_hint_rad, double t0_s, double gap_rad) const {
  Signals& s = st.s;
  s = Signals{};
  s.t_s = t0_s;
  s.gap_rad = gap_rad;
  s.theta_cmd_rad = cmd_rad;
  s.theta_valve_rad = valve_hint_rad;
  double* x = st.x.data();
  for (std::size_t i = 0; i < effects_.size(); ++i) {
    if (i == first_sensor_) s.p_meas_pa = s.p_chamber_pa;
    effects_[i]->settle({x + offsets_[i], effects_[i]->state_size()}, s);
  }
  if (first_sensor_ == effects_.size()) s.p_meas_pa = s.p_chamber_pa;
  return s.p_meas_pa;
}

void Plant::settle(PlantState& st, double p_meas_pa, double theta_cmd_rad, double t0_s, double gap_rad) const {
  settle_impl(st, p_meas_pa, theta_cmd_rad, t0_s, gap_rad, false);
}

double Plant::settle_nearest(PlantState& st, double p_meas_pa, double theta_cmd_rad, double t0_s, double gap_rad) const {
  return settle_impl(st, p_meas_pa, theta_cmd_rad, t0_s, gap_rad, true);
}

double Plant::settle_impl(PlantState& st, double p_meas_pa, double theta_cmd_rad, double t0_s, double gap_rad,
                          bool nearest) const {
  const bool positive_contact = std::isnan(theta_cmd_rad);
  settle_chain(st, 0.0, kNaN, t0_s, gap_rad);
  const double gap_now = std::isfinite(st.s.gap_rad) ? st.s.gap_rad : 0.0;
  auto pressure_at = [&](double valve_rad) {
    return settle_chain(st, positive_contact ? valve_rad + gap_now / 2 : theta_cmd_rad, valve_rad, t0_s, gap_rad);
  };
  double lo = kSearchLoRad, hi = kSearchHiRad;  // pressure falls as the valve opens
  const double p_hi = pressure_at(lo), p_lo = pressure_at(hi);
  if (nearest && std::isfinite(p_meas_pa)) p_meas_pa = std::clamp(p_meas_pa, p_lo, p_hi);
  if (!(p_meas_pa <= p_hi && p_meas_pa >= p_lo)) {
    char msg[200];
    std::snprintf(msg, sizeof msg, "pressure %.4g MPa is outside what the plant reaches (%.4g to %.4g MPa)",
                  units::pa_to_mpa(p_meas_pa), units::pa_to_mpa(p_lo), units::pa_to_mpa(p_hi));
    throw std::out_of_range(msg);
  }
  for (int i = 0; i < 80; ++i) {
    const double mid = 0.5 * (lo + hi);
    (pressure_at(mid) > p_meas_pa ? lo : hi) = mid;
  }
  return pressure_at(0.5 * (lo + hi));
}

std::pair<double, double> Plant::pressure_range_pa() const {
  PlantState st = make_state(1);
  // Motor and valve together at each end of the search window: the stops clamp the valve.
  const double p_low = settle_chain(st, kSearchHiRad, kSearchHiRad, 0.0, kNaN);
  const double p_high = settle_chain(st, kSearchLoRad, kSearchLoRad, 0.0, kNaN);
  return {p_low, p_high};
}

const Effect* Plant::find(std::string_view kind) const {
  for (const auto& e : effects_) {
    if (e->kind() == kind) return e.get();
  }
  return nullptr;
}

Plant Plant::with(std::shared_ptr<const Effect> effect) const {
  // In place when the kind is there: effects of one stage run in their order, and a refitted
  // backlash must stay before a stiction that modifies its output. A new kind goes last.
  std::vector<std::shared_ptr<const Effect>> out = effects_;
  const auto it = std::find_if(out.begin(), out.end(), [&](const auto& e) { return e->kind() == effect->kind(); });
  if (it != out.end())
    *it = std::move(effect);
  else
    out.push_back(std::move(effect));
  return Plant(std::move(out));
}

Plant Plant::without(std::string_view kind) const {
  std::vector<std::shared_ptr<const Effect>> out;
  for (const auto& e : effects_) {
    if (e->kind() != kind) out.push_back(e);
  }
  return Plant(std::move(out));
}

std::string Plant::to_yaml(std::string_view header_comment) const {
  std::ostringstream out;
  if (!header_comment.empty()) {
    std::istringstream lines{std::string(header_comment)};
    for (std::string line; std::getline(lines, line);) out << "# " << line << "\n";
  }
  out << "effects:\n";
  for (const auto& e : effects_) {
    out << "  " << e->kind() << ":";
    const auto params = e->params();
    const auto tables = e->tables();
    if (params.empty() && tables.empty()) {
      out << " {}\n";
      continue;
    }
    out << "\n";
    char buf[64];
    for (const auto& p : params) {
      std::snprintf(buf, sizeof buf, "%.10g", p.value);
      out << "    " << p.key << ": " << buf << "\n";
    }
    for (const auto& t : tables) {
      out << "    " << t.key << ": [";
      for (std::size_t i = 0; i < t.values.size(); ++i) {
        std::snprintf(buf, sizeof buf, "%.10g", t.values[i]);
        out << (i ? ", " : "") << buf;
      }
      out << "]\n";
    }
  }
  return out.str();
}

}  // namespace hil::plant
