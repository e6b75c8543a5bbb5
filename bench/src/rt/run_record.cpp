#include "hil/bench/rt/run_record.hpp"

#include <stdexcept>
#include <type_traits>

#include "hil/line_file.hpp"
#include "hil/json_file.hpp"

namespace hil::bench {

using nlohmann::json;

namespace {

json or_null(const std::optional<std::string>& s) { return s ? json(*s) : json(nullptr); }
json or_null(const std::optional<double>& v) { return v ? json(*v) : json(nullptr); }

// The reader's checks: a key of the wrong type names the file and the key.
struct Reader {
  const json& j;
  const std::string& origin;

  [[noreturn]] void fail(const std::string& key, const char* what) const {
    throw std::runtime_error(origin + ": key '" + key + "' " + what);
  }
  const json* find(const std::string& key) const {
    const auto it = j.find(key);
    return it == j.end() ? nullptr : &*it;
  }
  std::string text(const std::string& key) const {
    const json* v = find(key);
    if (v == nullptr) fail(key, "is missing");
    if (!v->is_string()) fail(key, "must be a string");
    return v->get<std::string>();
  }
  std::optional<std::string> text_or_null(const std::string& key) const {
    const json* v = find(key);
    if (v == nullptr || v->is_null()) return std::nullopt;
    if (!v->is_string()) fail(key, "must be a string or null");
    return v->get<std::string>();
  }
  double number(const std::string& key) const {
    const json* v = find(key);
    if (v == nullptr) fail(key, "is missing");
    if (!v->is_number()) fail(key, "must be a number");
    return v->get<double>();
  }
  std::optional<double> number_or_null(const std::string& key) const {
    const json* v = find(key);
    if (v == nullptr || v->is_null()) return std::nullopt;
    if (!v->is_number()) fail(key, "must be a number or null");
    return v->get<double>();
  }
  template <class Int>
  std::optional<Int> integer_if(const std::string& key) const {
    const json* v = find(key);
    if (v == nullptr || v->is_null()) return std::nullopt;
    if (std::is_unsigned_v<Int> ? !v->is_number_unsigned() : !v->is_number_integer()) {
      fail(key, std::is_unsigned_v<Int> ? "must be a count (a whole number >= 0)" : "must be a whole number");
    }
    return v->get<Int>();
  }
  const json& object(const std::string& key) const {
    const json* v = find(key);
    if (v == nullptr) fail(key, "is missing");
    if (!v->is_object()) fail(key, "must be an object");
    return *v;
  }
};

}  // namespace

std::string_view to_string(Outcome o) noexcept {
  switch (o) {
    case Outcome::completed: return "completed";
    case Outcome::stopped: return "stopped";
    case Outcome::aborted: return "aborted";
    case Outcome::error: return "error";
    case Outcome::interrupted: return "interrupted";
    case Outcome::running: return "running";
  }
  return "error";
}

Outcome outcome_from(std::string_view text) noexcept {
  for (const Outcome o :
       {Outcome::completed, Outcome::stopped, Outcome::aborted, Outcome::error, Outcome::interrupted, Outcome::running})
    if (to_string(o) == text) return o;
  return Outcome::error;
}

json RunRecord::to_json() const {
  json j = {{"version", version},
            {"host", host},
            {"pid", pid},
            {"campaign", campaign},
            {"run", run},
            {"run_index", run_index},
            {"runs_in_campaign", runs_in_campaign},
            {"rig", {{"name", rig_name}, {"kind", rig_kind}}},
            {"start_utc", start_utc},
            {"stop_utc", or_null(stop_utc)},
            {"outcome", std::string(to_string(outcome))},
            {"reason", or_null(reason)},
            {"period_s", period_s},
            {"duration_s", duration_s},
            {"speed", speed},
            {"config",
             {{"campaign_source", config.campaign_source},
              {"campaign_file", config.campaign_file},
              {"campaign_yaml", config.campaign_yaml},
              {"rig_file", config.rig_file},
              {"rig_yaml", config.rig_yaml},
              {"plant_file", config.plant_file},
              {"plant_yaml", config.plant_yaml}}}};
  if (ended) {
    j["trip"] = trip ? json{{"reason", trip->reason},
                            {"t_s", trip->t_s},
                            {"value", or_null(trip->value)},
                            {"limit", or_null(trip->limit)},
                            {"longest_gap_ms", or_null(trip->longest_gap_ms)},
                            {"longest_gap_t_s", or_null(trip->longest_gap_t_s)}}
                     : json(nullptr);
    j["rig_health"] = rig_health;
  }
  if (periods_run) j["periods_run"] = *periods_run;
  if (!loop.is_null()) j["loop"] = loop;
  if (telemetry) {
    json t = {{"file", telemetry->file}};
    auto put = [&t](const char* key, const auto& v) {
      if (v) t[key] = *v;
    };
    put("rows_written", telemetry->rows_written);
    put("rows_lost", telemetry->rows_lost);
    put("rows_unwritten", telemetry->rows_unwritten);
    put("events_lost", telemetry->events_lost);
    put("events_unwritten", telemetry->events_unwritten);
    put("ring_rows", telemetry->ring_rows);
    put("rows_expected", telemetry->rows_expected);
    if (telemetry->write_error_known) t["write_error"] = or_null(telemetry->write_error);
    j["telemetry"] = t;
  }
  if (!recorded_by.empty()) j["recorded_by"] = recorded_by;
  if (!interrupted.is_null()) j["interrupted"] = interrupted;
  if (!checks.is_null()) j["checks"] = checks;
  return j;
}

RunRecord RunRecord::from_json(const json& j, const std::string& origin) {
  if (!j.is_object()) throw std::runtime_error(origin + ": not a run record (not a JSON object)");
  const Reader r{j, origin};
  RunRecord rec;
  rec.version = r.text_or_null("version").value_or("");
  rec.host = r.text_or_null("host").value_or("");
  rec.pid = r.integer_if<std::int64_t>("pid").value_or(0);
  rec.recorded_by = r.text_or_null("recorded_by").value_or("");
  rec.campaign = r.text("campaign");
  rec.run = r.text("run");
  rec.run_index = r.integer_if<std::int64_t>("run_index").value_or(0);
  rec.runs_in_campaign = r.integer_if<std::int64_t>("runs_in_campaign").value_or(0);
  if (r.find("rig") != nullptr) {
    const Reader rig{r.object("rig"), origin};
    rec.rig_name = rig.text_or_null("name").value_or("");
    rec.rig_kind = rig.text_or_null("kind").value_or("");
  }
  rec.start_utc = r.text("start_utc");
  rec.stop_utc = r.text_or_null("stop_utc");
  rec.outcome = outcome_from(r.text("outcome"));
  rec.reason = r.text_or_null("reason");
  rec.period_s = r.number("period_s");
  rec.duration_s = r.number("duration_s");
  rec.speed = r.number_or_null("speed").value_or(1.0);
  const Reader cfg{r.object("config"), origin};
  rec.config = {cfg.text_or_null("campaign_source").value_or(""), cfg.text_or_null("campaign_file").value_or(""),
                cfg.text_or_null("campaign_yaml").value_or(""),   cfg.text_or_null("rig_file").value_or(""),
                cfg.text_or_null("rig_yaml").value_or(""),        cfg.text_or_null("plant_file").value_or(""),
                cfg.text_or_null("plant_yaml").value_or("")};
  if (const json* trip = r.find("trip")) {
    rec.ended = true;
    if (!trip->is_null()) {
      const Reader t{r.object("trip"), origin};
      rec.trip = Trip{t.text("reason"),
                      t.number("t_s"),
                      t.number_or_null("value"),
                      t.number_or_null("limit"),
                      trip->contains("longest_gap_ms") ? t.number_or_null("longest_gap_ms") : std::nullopt,
                      trip->contains("longest_gap_t_s") ? t.number_or_null("longest_gap_t_s") : std::nullopt};
    }
  }
  if (const json* h = r.find("rig_health")) rec.rig_health = *h;
  rec.periods_run = r.integer_if<std::int64_t>("periods_run");
  if (const json* l = r.find("loop")) rec.loop = *l;
  if (r.find("telemetry") != nullptr) {
    const Reader t{r.object("telemetry"), origin};
    Telemetry tel;
    tel.file = t.text_or_null("file").value_or("telemetry.csv");
    tel.rows_written = t.integer_if<std::uint64_t>("rows_written");
    tel.rows_lost = t.integer_if<std::uint64_t>("rows_lost");
    tel.rows_unwritten = t.integer_if<std::uint64_t>("rows_unwritten");
    tel.events_lost = t.integer_if<std::uint64_t>("events_lost");
    tel.events_unwritten = t.integer_if<std::uint64_t>("events_unwritten");
    tel.ring_rows = t.integer_if<std::uint64_t>("ring_rows");
    tel.rows_expected = t.integer_if<std::int64_t>("rows_expected");
    tel.write_error_known = t.find("write_error") != nullptr;
    tel.write_error = t.text_or_null("write_error");
    rec.telemetry = tel;
  }
  if (const json* i = r.find("interrupted")) rec.interrupted = *i;
  if (const json* c = r.find("checks")) rec.checks = *c;
  return rec;
}

RunRecord read_run_record(const std::filesystem::path& dir) {
  const auto file = dir / "run.json";
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec))
    throw std::runtime_error(dir.string() + ": no run.json (not a run folder of hilbench serve)");
  return RunRecord::from_json(read_json_file(file), file.string());
}

void write_run_record(const std::filesystem::path& dir, const RunRecord& record) {
  replace_file(dir / "run.json", record.to_json().dump(2, ' ', false, json::error_handler_t::replace) + "\n");
}

}  // namespace hil::bench
