#include "hidden_suite.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>

#include "hil/analysis/candidates.hpp"
#include "hil/analysis/compare.hpp"
#include "hil/plant/rng.hpp"

namespace hil::test::suite {
namespace {

namespace fs = std::filesystem;
using plant::Plant;

// The effects a file may hide. Magnitudes: what wear, assembly and instruments do on such a rig,
// large enough to matter at 5 kPa on 30 s (every draw's cost is measured anyway: identifiable).
struct Kind {
  std::string tag, candidate, block, key;
  double lo, hi;
  bool either_sign = false;
  bool command_side = false;  // before the motor: invisible with the encoder (never drawn with it)
  bool refit = false;         // a parameter of the model's own block
};

const std::vector<Kind>& kinds() {
  static const std::vector<Kind> k = {
      {"gap", "backlash_change", "backlash_change", "gap_deg", 1.4, 1.9},
      {"offset", "valve_offset", "valve_offset", "offset_deg", 0.5, 1.0, true},
      {"erosion", "throat_erosion", "throat_erosion", "rate_mm2_per_s", 0.3, 0.5},
      {"lag", "sensor_lag", "sensor_lag", "time_constant_s", 0.012, 0.03},
      {"delay", "transport_delay", "transport_delay", "delay_s", 0.02, 0.04, false, true},
      {"bias", "sensor_bias", "sensor_bias", "offset_kpa", 15, 30, true},
      {"servo", "motor_dynamics", "motor_servo", "time_constant_s", 0.03, 0.045, false, true, true},
      {"burn", "burn_rate", "gas_generator", "burn_rate_mm_s_at_1mpa", 5.3, 5.45, false, false, true},
  };
  return k;
}

const Kind& kind(const std::string& tag) {
  for (const auto& k : kinds())
    if (k.tag == tag) return k;
  throw std::invalid_argument("hidden suite: no effect '" + tag + "'");
}

// Pairs analysis/README.md (Limits) names as not told apart from pressure on such files.
bool confusable(const std::string& a, const std::string& b) {
  auto is = [&](const char* x, const char* y) { return (a == x && b == y) || (a == y && b == x); };
  return is("offset", "bias") || is("offset", "burn") || is("bias", "burn");
}

// The candidate's fit prior must hold the truth: its name, the key in one of its forms, the value
// inside its search range. The neutral value ("no change") is the candidate's attached model's.
double neutral_of(const Kind& k, const Plant& nominal, double value) {
  for (const auto& c : analysis::candidates_for(nominal, {k.candidate})) {
    for (const auto& v : c.variants)
      for (const auto& p : v.params) {
        if (p.key != k.key) continue;
        if (value < p.lo || value > p.hi)
          throw std::invalid_argument("hidden suite: " + k.candidate + "." + k.key + " = " + std::to_string(value) +
                                      " outside its fit prior's range");
        return analysis::value_of(c.attach(nominal), p.effect, k.key);
      }
  }
  throw std::invalid_argument("hidden suite: no candidate " + k.candidate + " with " + k.key + " (fit priors changed?)");
}

std::string num(double v, const char* fmt = "%g") {
  char b[64];
  std::snprintf(b, sizeof b, fmt, v);
  return b;
}

// --- references -------------------------------------------------------------------------------

// A pressure reference for the closed loop [MPa], as a campaign's `reference:` block.
std::string reference_yaml(Reference r, plant::Rng& rng, double duration_s) {
  std::string t_list, p_list;
  auto point = [&](double t, double p) {
    t_list += (t_list.empty() ? "" : ", ") + num(t, "%.3f");
    p_list += (p_list.empty() ? "" : ", ") + num(p, "%.4f");
  };
  if (r == Reference::random_walk) {
    // Increments every 0.3-0.6 s, reflected at the ends of 0.85-1.6 MPa.
    double p = 1.1 + 0.2 * rng.uniform();
    for (double t = 1.0; t < duration_s; t += 0.3 + 0.3 * rng.uniform()) {
      p += 0.14 * (2 * rng.uniform() - 1);
      if (p < 0.85) p = 1.7 - p;
      if (p > 1.6) p = 3.2 - p;
      point(t, p);
    }
    return "  initial_mpa: 1.2\n  profile:\n    - points: {t_s: [" + t_list + "], p_mpa: [" + p_list + "]}\n";
  }
  if (r == Reference::prbs) {
    // A 7-bit maximal-length shift register between two levels, bit time 0.35-0.7 s.
    const double lo = 0.88 + 0.12 * rng.uniform(), hi = 1.35 + 0.2 * rng.uniform(), bit_s = 0.35 + 0.35 * rng.uniform();
    unsigned state = 1 + static_cast<unsigned>(rng.uniform() * 126);
    std::string s = "  initial_mpa: " + num(lo) + "\n  profile:\n";
    bool high = false;
    for (double t = 1.0; t < duration_s - 0.1; t += bit_s) {
      const unsigned bit = ((state >> 6) ^ (state >> 5)) & 1u;
      state = ((state << 1) | bit) & 0x7fu;
      if ((bit != 0) != high) {
        high = bit != 0;
        s += "    - step: {at_s: " + num(t, "%.3f") + ", to_mpa: " + num(high ? hi : lo) + "}\n";
      }
    }
    return s;
  }
  // A throttling mission: boost, throttle down, cruise with corrections, a dash, throttle down.
  const double f = duration_s / 30;
  const double boost = 1.45 + 0.1 * rng.uniform(), cruise = 0.95 + 0.1 * rng.uniform(), dash = 1.35 + 0.15 * rng.uniform();
  point(1.0 * f, boost);
  point((5 + rng.uniform()) * f, boost);
  point((7 + rng.uniform()) * f, cruise);
  for (double t = 8.5; t < 16; t += 1.2 + rng.uniform()) point(t * f, cruise + 0.12 * (2 * rng.uniform() - 1));
  point(17 * f, cruise);
  point((18 + rng.uniform()) * f, dash);
  point((22 + rng.uniform()) * f, dash);
  point((24 + rng.uniform()) * f, 0.9);
  point(27.5 * f, 1.05);
  return "  initial_mpa: " + num(cruise) + "\n  profile:\n    - points: {t_s: [" + t_list + "], p_mpa: [" + p_list + "]}\n";
}

// A command for the DAQ's open loop [deg] against time since the first row (about 1 MPa at 11 deg).
std::function<double(double)> command_deg(Reference r, plant::Rng& rng, double duration_s) {
  std::vector<std::pair<double, double>> pts;  // linear between points
  if (r == Reference::random_walk) {
    double a = 10 + rng.uniform();
    for (double t = 0; t < duration_s + 1; t += 0.25 + 0.25 * rng.uniform()) {
      a += 1.0 * (2 * rng.uniform() - 1);
      if (a < 7.5) a = 15 - a;
      if (a > 13) a = 26 - a;
      pts.push_back({t, a});
    }
  } else if (r == Reference::prbs) {
    const double lo = 8 + rng.uniform(), hi = 11.5 + 1.5 * rng.uniform(), bit_s = 0.3 + 0.4 * rng.uniform();
    unsigned state = 1 + static_cast<unsigned>(rng.uniform() * 126);
    double a = lo;
    pts.push_back({0, a});
    for (double t = 0.5; t < duration_s + 1; t += bit_s) {
      const unsigned bit = ((state >> 6) ^ (state >> 5)) & 1u;
      state = ((state << 1) | bit) & 0x7fu;
      pts.push_back({t, a});
      a = bit ? hi : lo;
      pts.push_back({t + 0.02, a});  // a 20 ms edge: the drive's rate limit shapes it anyway
    }
  } else {
    const double f = duration_s / 30;
    const double boost = 7.8 + 0.5 * rng.uniform(), cruise = 11 + rng.uniform(), dash = 8.6 + 0.6 * rng.uniform();
    pts = {{0, cruise}, {1 * f, boost}, {6 * f, boost}, {8 * f, cruise}};
    for (double t = 9; t < 16; t += 1.2 + rng.uniform()) pts.push_back({t * f, cruise + 0.8 * (2 * rng.uniform() - 1)});
    pts.push_back({17 * f, cruise});
    pts.push_back({(18.5 + rng.uniform()) * f, dash});
    pts.push_back({23 * f, dash});
    pts.push_back({25 * f, 12.8});
    pts.push_back({31 * f, 12.0});
  }
  return [pts](double t) {
    if (t <= pts.front().first) return pts.front().second;
    for (std::size_t i = 1; i < pts.size(); ++i) {
      if (t > pts[i].first) continue;
      const auto [t0, a0] = pts[i - 1];
      const auto [t1, a1] = pts[i];
      return t1 > t0 ? a0 + (a1 - a0) * (t - t0) / (t1 - t0) : a1;
    }
    return pts.back().second;
  };
}

const char* reference_name(Reference r) {
  return r == Reference::random_walk ? "random walk" : r == Reference::prbs ? "PRBS" : "mission";
}

// --- noise ------------------------------------------------------------------------------------

SensorNoise noise_of(const std::string& colour, double level_kpa, bool daq, std::uint64_t seed) {
  SensorNoise n{.coloured_kpa = level_kpa, .white_kpa = 0.3, .step_kpa = daq ? 1.0 : 0.0, .seed = seed};
  double v = 0;
  if (std::sscanf(colour.c_str(), "AR(1) phi %lf", &v) == 1) {
    n.phi = v;
  } else if (std::sscanf(colour.c_str(), "filter %lf Hz", &v) == 1) {
    n.filter_hz = v;
  } else {
    throw std::invalid_argument("hidden suite: unknown noise colour '" + colour + "'");
  }
  return n;
}

std::uint64_t mix(std::uint64_t a, std::uint64_t b) {
  plant::Rng r(a * 0x9e3779b97f4a7c15ULL + b);
  return r.next();
}

// The rest of a file's draw (reference, logger, encoder, compensation, its seed) from `rng`.
void draw_setup(SuiteFile& f, plant::Rng& rng, double daq_share) {
  const double u = rng.uniform();
  f.reference = u < 1.0 / 3 ? Reference::random_walk : (u < 2.0 / 3 ? Reference::prbs : Reference::mission);
  f.logger = rng.uniform() < daq_share ? Logger::daq : Logger::bench;
  f.encoder = rng.uniform() < (f.logger == Logger::daq ? 0.3 : 0.4);
  const double c = rng.uniform();
  f.compensation = c < 1.0 / 3 ? "none" : (c < 2.0 / 3 ? "constant" : "adaptive");
  f.seed = rng.next() % 1000000 + 1;
}

std::vector<Hidden> hidden_of(const std::vector<std::string>& tags, plant::Rng& rng, const Plant& nominal) {
  std::vector<Hidden> out;
  for (const auto& tag : tags) {
    const Kind& k = kind(tag);
    double v = k.lo + (k.hi - k.lo) * rng.uniform();
    if (k.either_sign && rng.uniform() < 0.5) v = -v;
    v = std::stod(num(v, "%.4g"));  // as a person would write it
    out.push_back({k.tag, k.candidate, k.key, v, neutral_of(k, nominal, v)});
  }
  return out;
}

// `n` distinct tags, none command-side with the encoder, no confusable pair.
std::vector<std::string> draw_tags(int n, bool encoder, plant::Rng& rng) {
  while (true) {
    std::vector<std::string> tags;
    for (int tries = 0; static_cast<int>(tags.size()) < n && tries < 100; ++tries) {
      const Kind& k = kinds()[static_cast<std::size_t>(rng.uniform() * static_cast<double>(kinds().size()))];
      if (k.command_side && encoder) continue;
      if (std::find(tags.begin(), tags.end(), k.tag) != tags.end()) continue;
      if (std::any_of(tags.begin(), tags.end(), [&](const std::string& t) { return confusable(t, k.tag); })) continue;
      tags.push_back(k.tag);
    }
    if (static_cast<int>(tags.size()) == n) return tags;
  }
}

}  // namespace

std::vector<std::string> colours() {
  return {"AR(1) phi 0.3", "AR(1) phi 0.55", "AR(1) phi 0.8", "filter 50 Hz", "filter 100 Hz", "filter 200 Hz"};
}
std::vector<double> levels_kpa() { return {1.0, 2.5, 5.0}; }

Plant SuiteFile::truth(const Plant& nominal, int except) const {
  Plant p = nominal;
  for (std::size_t i = 0; i < hidden.size(); ++i) {
    if (static_cast<int>(i) == except) continue;
    const Hidden& h = hidden[i];
    const Kind& k = kind(h.tag);
    if (k.refit) {
      p = with_param(p, k.block, k.key, h.value);
    } else if (k.block == "sensor_bias") {
      p = with_block(p, k.block, "{offset_kpa: " + num(h.value) + ", gain: 1.0}");
    } else {
      p = with_block(p, k.block, k.key + ": " + num(h.value));
    }
  }
  return p;
}

std::string SuiteFile::effects_text() const {
  if (hidden.empty()) return "none";
  std::vector<std::string> tags;
  for (const auto& h : hidden) tags.push_back(h.tag);
  std::sort(tags.begin(), tags.end());
  std::string s;
  for (const auto& t : tags) s += (s.empty() ? "" : "+") + t;
  return s;
}

SuiteFile draw_file(std::uint64_t seed, const std::string& name, const std::vector<std::string>& tags, const std::string& colour,
                    double level_kpa, Logger logger, double duration_s) {
  plant::Rng rng(seed);
  SuiteFile f;
  f.name = name;
  f.duration_s = duration_s;
  draw_setup(f, rng, 0.25);
  f.logger = logger;
  if (std::any_of(tags.begin(), tags.end(), [](const std::string& t) { return kind(t).command_side; })) f.encoder = false;
  f.hidden = hidden_of(tags, rng, Plant::load(nominal_model()));
  f.colour = colour;
  f.level_kpa = level_kpa;
  f.noise = noise_of(colour, level_kpa, f.logger == Logger::daq, mix(seed, 99));
  return f;
}

std::vector<SuiteFile> draw_suite(const SuiteSpec& spec) {
  const Plant nominal = Plant::load(nominal_model());
  plant::Rng rng(spec.seed);
  std::vector<SuiteFile> out;
  const auto cs = colours();
  const auto ls = levels_kpa();
  // Healthy: every colour at every level.
  for (const auto& c : cs)
    for (const double l : ls)
      for (int i = 0; i < spec.healthy_per_noise; ++i) {
        SuiteFile f;
        draw_setup(f, rng, spec.daq_share);
        f.duration_s = spec.duration_s;
        f.colour = c;
        f.level_kpa = l;
        f.noise = noise_of(c, l, f.logger == Logger::daq, rng.next());
        f.name = "healthy_" + std::to_string(out.size());
        out.push_back(std::move(f));
      }
  // With effects: colour and level drawn.
  for (const auto& [n, count] : {std::pair{1, spec.singles}, {2, spec.pairs}, {3, spec.triples}})
    for (int i = 0; i < count; ++i) {
      SuiteFile f;
      draw_setup(f, rng, spec.daq_share);
      f.duration_s = spec.duration_s;
      f.hidden = hidden_of(draw_tags(n, f.encoder, rng), rng, nominal);
      f.colour = cs[static_cast<std::size_t>(rng.uniform() * static_cast<double>(cs.size()))];
      f.level_kpa = ls[static_cast<std::size_t>(rng.uniform() * static_cast<double>(ls.size()))];
      f.noise = noise_of(f.colour, f.level_kpa, f.logger == Logger::daq, rng.next());
      std::string tags = f.effects_text();
      std::replace(tags.begin(), tags.end(), '+', '_');
      f.name = "e" + std::to_string(out.size()) + "_" + tags;
      out.push_back(std::move(f));
    }
  return out;
}

fs::path write_file(const SuiteFile& f, const fs::path& dir) {
  plant::Rng rng(mix(f.seed, 7));
  fs::path file;
  if (f.logger == Logger::bench) {
    Scenario s;
    s.name = f.name;
    s.duration_s = f.duration_s;
    s.seed = f.seed;
    s.noise_kpa = 0;  // the transducer's noise is added below
    s.reference_yaml = reference_yaml(f.reference, rng, f.duration_s);
    s.compensation = f.compensation;
    s.encoder = f.encoder;
    s.truth = [&f](const Plant& p) { return f.truth(p); };
    file = make_measurement(s, dir);
  } else {
    LabLog lab;
    lab.name = f.name;
    lab.duration_s = f.duration_s;
    lab.seed = f.seed;
    lab.t0_s = 1.7e9 + std::floor(1e6 * rng.uniform());  // a Unix time stamp
    lab.noise_kpa = 0;
    lab.plant_t0_s = 0;  // effects count from the log's start, the time stamps are the DAQ's
    lab.encoder = f.encoder;
    lab.command_deg = command_deg(f.reference, rng, f.duration_s);
    // One to three holes of 20-80 ms (a logger's buffer overrun).
    const int holes = 1 + static_cast<int>(3 * rng.uniform());
    for (int i = 0; i < holes; ++i) {
      const double at = 3 + (f.duration_s - 6) * rng.uniform();
      lab.holes_s.push_back({at, at + 0.02 + 0.06 * rng.uniform()});
    }
    lab.truth = [&f](const Plant& p) { return f.truth(p); };
    file = make_lab_log(lab, dir);
  }
  add_sensor_noise(file, f.noise);
  return file;
}

Score score(const SuiteFile& f, const analysis::Measurement& m, const analysis::Diagnosis& d) {
  Score s;
  s.name = f.name;
  s.effects = f.effects_text();
  s.colour = f.colour;
  s.level_kpa = f.level_kpa;
  s.reference = reference_name(f.reference);
  s.logger = f.logger == Logger::daq ? "DAQ" : "bench";
  s.encoder = f.encoder;
  s.n_effects = static_cast<int>(f.hidden.size());
  s.verdict = d.verdict;
  s.fit_before_pct = d.fit_before_pct;
  s.fit_after_pct = d.fit_after_pct;
  s.floor_pct = d.noise_floor_fit_pct;
  s.wall_s = d.wall_s;
  std::vector<std::string> found, expected;
  for (const auto& a : d.added) found.push_back(a.effect);
  for (const auto& h : f.hidden) expected.push_back(h.candidate);
  std::sort(found.begin(), found.end());
  std::sort(expected.begin(), expected.end());
  for (const auto& e : found) s.found += (s.found.empty() ? "" : "+") + e;
  s.right_set = found == expected;
  if (f.hidden.empty()) {
    s.pass = d.verdict == "nothing_missing" && d.added.empty();
    return s;
  }
  // Identifiable: no confusable pair, and each effect's absence from the truth costs at least half
  // the noise power on this file.
  for (std::size_t i = 0; i < f.hidden.size(); ++i)
    for (std::size_t j = i + 1; j < f.hidden.size(); ++j)
      if (confusable(f.hidden[i].tag, f.hidden[j].tag)) {
        s.identifiable = false;
        s.why_not_identifiable = f.hidden[i].tag + " with " + f.hidden[j].tag + " (analysis/README.md, Limits)";
      }
  const Plant nominal = Plant::load(nominal_model());
  auto rss = [&](const Plant& model) { return analysis::compare_measurement(model, m, false).rss_pa2; };
  const double noise_power = static_cast<double>(m.rows.size()) * std::pow(1e3 * f.noise.total_kpa(), 2);
  const double truth_rss = rss(f.truth(nominal));
  s.min_drop_cost = INFINITY;
  for (std::size_t i = 0; i < f.hidden.size(); ++i) {
    const double cost = (rss(f.truth(nominal, static_cast<int>(i))) - truth_rss) / noise_power;
    s.min_drop_cost = std::min(s.min_drop_cost, cost);
    if (cost < 0.5 && s.identifiable) {
      s.identifiable = false;
      s.why_not_identifiable = "dropping " + f.hidden[i].tag + " costs " + num(cost, "%.2f") + " of the noise power";
    }
  }
  bool within = s.right_set;
  for (const auto& h : f.hidden) {
    double v = NAN;
    for (const auto& a : d.added)
      if (a.effect == h.candidate)
        for (const auto& p : a.parameters)
          if (p.key == h.key) v = p.value;
    const double err = std::abs(v - h.value) / std::abs(h.value);
    s.worst_error = std::max(s.worst_error, std::isfinite(err) ? err : INFINITY);
    within = within && err <= 0.15;
    s.params +=
        (s.params.empty() ? "" : "; ") + h.tag + " " + h.key + " " + num(v, "%.4g") + " (truth " + num(h.value) +
        (std::isfinite(err) ? ", " + num(100 * (v - h.value) / h.value, "%+.1f") + " %" : "") +
        (std::isfinite(v) ? ", of the change " + num(100 * std::abs(v - h.value) / std::abs(h.value - h.neutral), "%.0f") + " %"
                          : "") +
        ")";
  }
  s.pass = within;
  return s;
}

Score run_file(const SuiteFile& f, const fs::path& dir, unsigned threads) {
  const fs::path file = write_file(f, dir);
  const analysis::Measurement m = analysis::load_measurement(file);
  analysis::DiagnoseSettings settings;
  settings.threads = threads;
  settings.keep_series = false;
  const auto t0 = std::chrono::steady_clock::now();
  const analysis::Diagnosis d = analysis::diagnose(Plant::load(nominal_model()), m, settings);
  Score s = score(f, m, d);
  s.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return s;
}

}  // namespace hil::test::suite
