// Control of the bench: its status, starting a campaign (a file of the campaigns folder or a
// posted one, on a rig of the rigs folder), stopping, aborting, injecting gap changes and faults.
#include <algorithm>
#include <cmath>
#include <optional>

#include <spdlog/spdlog.h>

#include "api_router.hpp"
#include "hil/config.hpp"
#include "hil/text_file.hpp"
#include "hil/units.hpp"

namespace hil::bench::api {
namespace {

const FieldSpecs kStartBody = {
    {"campaign", FieldType::text, "", -INFINITY, INFINITY, false, "a campaign's name from GET /api/campaigns"},
    {"campaign_yaml", FieldType::text, "", -INFINITY, INFINITY, false, "a campaign itself (YAML)"},
    {"rig", FieldType::text, "", -INFINITY, INFINITY, false, "a rig's name from GET /api/rigs (sim when not given)"},
    {"runs", FieldType::text_list, "", -INFINITY, INFINITY, false, "the runs to run (all when not given)"},
    {"speed", FieldType::number, "times real time", -INFINITY, INFINITY, false, "the runner checks its range"},
};
// A YAML body's options (the same, in the query).
const FieldSpecs kStartQuery = {
    {"rig", FieldType::text},
    {"runs", FieldType::text, "", -INFINITY, INFINITY, false, "comma-separated"},
    {"speed", FieldType::number, "times real time"},
};
const FieldSpecs kAbortBody = {{"reason", FieldType::text, "", -INFINITY, INFINITY, false, "one line, at most 500 bytes"}};

// The fields of each injection; its values' ranges are check_injection's (runner.hpp), checked in
// runner.inject: one table for every client.
const FieldSpecs kGapFields = {{"gap_deg", FieldType::number, "deg"}, {"programme", FieldType::flag}};
const FieldSpecs kSensorFields = {{"mode", FieldType::text},
                                  {"bias_kpa", FieldType::number, "kPa"},
                                  {"rms_kpa", FieldType::number, "kPa"},
                                  {"duration_s", FieldType::number, "s"}};
const FieldSpecs kDriveFields = {{"mode", FieldType::text}, {"on", FieldType::flag}, {"duration_s", FieldType::number, "s"}};
const FieldSpecs kRigFields = {{"mode", FieldType::text}, {"on", FieldType::flag}};
const FieldSpecs kClearFields = {};

// Every injection's fields, once each: the route's declaration (GET /api's fuzz requests).
FieldSpecs inject_fields() {
  FieldSpecs all;
  for (const auto* kind : {&kGapFields, &kSensorFields, &kDriveFields, &kRigFields}) {
    for (const auto& f : *kind) {
      if (std::none_of(all.begin(), all.end(), [&](const FieldSpec& a) { return a.name == f.name; })) all.push_back(f);
    }
  }
  return all;
}

RigConfig rig_named(const ApiServer::Impl& api, const std::string& name) {
  const auto names = yaml_stems(api.options.rigs_dir);
  if (!cfg::plain_name(name) || std::find(names.begin(), names.end(), name) == names.end()) {
    const std::string hint = cfg::closest(name, names);
    throw ApiError{http::status::not_found, "unknown rig",
                   "'" + name + "' is not a rig in " + api.options.rigs_dir.string() +
                       (hint.empty() ? "" : " (did you mean '" + hint + "'?)")};
  }
  if (!resolves_inside(api.options.rigs_dir / (name + ".yaml"), api.options.rigs_dir)) {
    throw ApiError{http::status::conflict, "rig file not read",
                   (api.options.rigs_dir / (name + ".yaml")).string() + " is a symbolic link to a file outside " +
                       api.options.rigs_dir.string() + ": not read",
                   "rig"};
  }
  try {
    return load_rig_config(api.options.rigs_dir / (name + ".yaml"));
  } catch (const cfg::Error& e) {
    // The request is sound, the rig it names is not usable as its files stand: a conflict with the
    // bench's state that the operator fixes in the file (GET /api/rigs lists the same error), not
    // a server failure.
    throw ApiError{http::status::conflict, "invalid rig file", e.what(), "rig"};
  }
}

Reply start(const Call& c) {
  ApiServer::Impl& api = c.api;
  const Request& req = c.req;
  const Target& t = c.target;
  if (const std::string why = api.refusing(); !why.empty())
    throw ApiError{http::status::service_unavailable, "not accepting campaigns", why};
  const std::string content_type(req[http::field::content_type]);
  const bool yaml_body = content_type.find("yaml") != std::string::npos;
  const Fields body = yaml_body ? Fields(json::object(), c.route.body) : c.body();
  if (!yaml_body) {
    // The query's options (the route's) are a YAML body's: beside a JSON body they were ignored,
    // and ?rig=hybrid started on sim.
    for (const auto& item : t.query) {
      if (item.first == "token") continue;
      const std::string shown = loggable_target(item.first);
      throw ApiError{http::status::bad_request, "unknown query option",
                     "'" + shown + "': a JSON body carries its options in the body; the query carries them for a YAML body",
                     shown};
    }
  }
  // Options come from the JSON body, or from the query when the body is the YAML itself.
  auto option = [&](const char* key) -> std::optional<std::string> {
    if (yaml_body) {
      const auto q = t.query.find(key);
      return q == t.query.end() ? std::nullopt : std::optional<std::string>(q->second);
    }
    return std::nullopt;
  };

  StartRequest s;
  const std::string rig = yaml_body ? option("rig").value_or("sim") : body.text("rig", "sim");
  s.rig = rig_named(api, rig);
  const std::string warning = rig_warning(s.rig);
  if (yaml_body) {
    if (const auto runs = option("runs")) s.runs = cfg::comma_list(*runs);
    if (option("speed")) s.speed = query_number(t, spec_of(c.route.query, "speed"), s.speed);
  } else {
    s.runs = body.text_list("runs");
    if (body.has("speed")) s.speed = body.number("speed");
  }
  // No subset means every run. A subset given empty ([], ?runs=, a name lost to a bug in a script)
  // ran them all, the opposite of a choice; a name given twice is a mistake too.
  const bool runs_given = yaml_body ? option("runs").has_value() : body.given("runs");
  if (runs_given && s.runs.empty()) {
    throw ApiError{http::status::bad_request, "bad field",
                   "'runs' names no run: name at least one, or leave 'runs' out to run them all", "runs"};
  }
  if (const std::string* twice = cfg::repeated(s.runs))
    throw ApiError{http::status::bad_request, "bad field", "'runs' names '" + *twice + "' twice", "runs"};

  std::string yaml;
  if (yaml_body) {
    yaml = req.body();
  } else if (body.has("campaign_yaml")) {
    yaml = body.text("campaign_yaml", "");
  }
  try {
    if (yaml_body || body.has("campaign_yaml")) {
      if (body.has("campaign"))
        throw ApiError{http::status::bad_request, "bad request", "give 'campaign' or 'campaign_yaml', not both"};
      s.campaign =
          load_campaign_text(yaml, "posted campaign", api.options.campaigns_dir, api.options.campaigns_dir.parent_path());
      s.source = "posted";
    } else {
      if (!body.has("campaign")) {
        throw ApiError{http::status::bad_request, "bad request",
                       "give 'campaign' (a name from GET /api/campaigns) or 'campaign_yaml'"};
      }
      const std::string name = body.text("campaign", "");
      const auto names = yaml_stems(api.options.campaigns_dir);
      if (!cfg::plain_name(name) || std::find(names.begin(), names.end(), name) == names.end()) {
        const std::string hint = cfg::closest(name, names);
        throw ApiError{http::status::not_found, "unknown campaign",
                       "'" + name + "' is not a campaign in " + api.options.campaigns_dir.string() +
                           (hint.empty() ? "" : " (did you mean '" + hint + "'?)")};
      }
      const auto file = api.options.campaigns_dir / (name + ".yaml");
      if (!resolves_inside(file, api.options.campaigns_dir)) {
        throw ApiError{
            http::status::conflict, "campaign file not read",
            file.string() + " is a symbolic link to a file outside " + api.options.campaigns_dir.string() + ": not read",
            "campaign"};
      }
      s.campaign = load_campaign(file);
      s.source = file.string();
    }
  } catch (const ApiError&) {
    throw;
  } catch (const std::exception& e) {  // cfg::Error, and anything a malformed file makes a loader throw
    throw ApiError{http::status::bad_request, "invalid campaign YAML", e.what()};
  }
  const std::string name = s.campaign.name;
  try {
    api.runner.start(std::move(s));
  } catch (const Conflict& e) {
    throw ApiError{http::status::conflict, "a campaign is running", e.what()};
  } catch (const InsufficientStorage& e) {
    throw ApiError{http::status::insufficient_storage, "no room for the record", e.what()};
  } catch (const BadField& e) {
    throw ApiError{http::status::bad_request, "cannot start", e.what(), e.field};
  } catch (const std::invalid_argument& e) {
    throw ApiError{http::status::bad_request, "cannot start", e.what()};
  }
  spdlog::info("campaign '{}' started", name);
  json reply = {{"started", name}, {"rig", rig}, {"status", api.runner.status()}};
  if (!warning.empty()) {
    spdlog::warn("{}", warning);
    reply["warning"] = warning;
  }
  return json_reply(http::status::accepted, reply);
}

Reply inject(const Call& c) {
  const std::string& what = c.args[0];
  const json request = parse_json_body(c.req);
  LoopRequest r;
  using K = LoopRequest::Kind;
  std::optional<Fields> fields;
  auto duration = [&] { return fields->has("duration_s") ? fields->number("duration_s") : 0.0; };
  if (what == "gap") {
    fields.emplace(request, kGapFields);
    if (fields->flag("programme", false)) {
      r.kind = K::programme_gap;
    } else {
      r.kind = K::set_gap;
      r.value = units::deg_to_rad(fields->number("gap_deg"));
    }
  } else if (what == "sensor") {
    fields.emplace(request, kSensorFields);
    const std::string mode = fields->text("mode", "");
    r.kind = K::sensor_fault;
    r.duration_s = duration();
    if (mode == "stuck") {
      r.sensor = SensorFault::stuck;
    } else if (mode == "dropout") {
      r.sensor = SensorFault::dropout;
    } else if (mode == "bias") {
      r.sensor = SensorFault::bias;
      r.value = fields->number("bias_kpa") * units::kPaPerKpa;
    } else if (mode == "noise") {
      r.sensor = SensorFault::noise;
      r.value = fields->number("rms_kpa") * units::kPaPerKpa;
      if (r.value < 0) throw ApiError{http::status::bad_request, "bad field", "'rms_kpa' must be >= 0"};
    } else {
      throw ApiError{http::status::bad_request, "bad field", "'mode' must be stuck, dropout, bias or noise"};
    }
  } else if (what == "drive") {
    fields.emplace(request, kDriveFields);
    const std::string mode = fields->text("mode", "ignore_commands");
    if (mode != "ignore_commands") throw ApiError{http::status::bad_request, "bad field", "'mode' must be ignore_commands"};
    r.kind = K::drive_fault;
    r.on = fields->flag("on", true);
    r.duration_s = duration();
  } else if (what == "rig") {
    fields.emplace(request, kRigFields);
    const std::string mode = fields->text("mode", "silent");
    if (mode != "silent") throw ApiError{http::status::bad_request, "bad field", "'mode' must be silent"};
    r.kind = K::rig_fault;
    r.on = fields->flag("on", true);
  } else if (what == "clear") {
    fields.emplace(request, kClearFields);
    r.kind = K::clear_faults;
  } else {
    const std::string hint = cfg::closest(what, {"gap", "sensor", "drive", "rig", "clear"});
    throw ApiError{
        http::status::not_found, "unknown injection",
        "'" + what + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)") + "; use gap, sensor, drive, rig or clear"};
  }
  try {
    c.api.runner.inject(r);
  } catch (const Conflict& e) {
    throw ApiError{http::status::conflict, "nothing to inject into", e.what()};
  } catch (const BadField& e) {  // a value outside check_injection's table
    throw ApiError{http::status::bad_request, "bad field", e.what(), e.field};
  } catch (const std::invalid_argument& e) {
    throw ApiError{http::status::bad_request, "not possible on this rig", e.what()};
  }
  return json_reply(http::status::accepted, {{"injected", what}, {"request", request}});
}

Reply stop(ApiServer::Impl& api) {
  try {
    api.runner.stop();
  } catch (const Conflict& e) {
    throw ApiError{http::status::conflict, "nothing to stop", e.what()};
  }
  return json_reply(http::status::accepted, {{"stopping", true}});
}

Reply abort(const Call& c) {
  const Fields body = c.body();
  const std::string given = body.text("reason", "no reason given");
  // The reason goes as it is into the server log, run.json and the console: a newline or an escape
  // sequence in it forged whole log lines ("[info] campaign ... started") and drove the terminal
  // of whoever read the log. C1 controls (U+0080..U+009F: 0xC2 0x80..0x9F in UTF-8) included.
  constexpr std::size_t kMaxReasonBytes = 500;
  bool control = false;
  for (std::size_t i = 0; i < given.size(); ++i) {
    const auto c = static_cast<unsigned char>(given[i]);
    const auto next = i + 1 < given.size() ? static_cast<unsigned char>(given[i + 1]) : 0;
    control = control || c < 0x20 || c == 0x7f || (c == 0xc2 && next >= 0x80 && next <= 0x9f);
  }
  if (control || given.size() > kMaxReasonBytes) {
    throw ApiError{http::status::bad_request, "bad field",
                   "'reason' must be one line of at most " + std::to_string(kMaxReasonBytes) +
                       " bytes without control characters, got '" + printable(given, 60) + "'",
                   "reason"};
  }
  const std::string reason = "operator abort: " + given;
  std::string ends_with;
  try {
    ends_with = c.api.runner.abort(reason);
  } catch (const Conflict& e) {
    throw ApiError{http::status::conflict, "nothing to abort", e.what()};
  }
  json answer = {{"aborting", true}, {"reason", ends_with}};
  if (ends_with != reason) answer["note"] = "an abort was already under way; the campaign ends with its reason";
  return json_reply(http::status::accepted, answer);
}

}  // namespace

std::vector<Route> control_routes() {
  return {
      {80, http::verb::get, "/api/status", "the campaign running now, its loop's health and interlocks",
       [](const Call& c) { return json_reply(http::status::ok, c.api.runner.status()); }},
      {90, http::verb::post, "/api/start", "start a campaign: {campaign | campaign_yaml, rig, runs, speed}", start, kStartQuery,
       kStartBody, Thread::worker},
      {100, http::verb::post, "/api/stop", "end the campaign after the run's current period",
       [](const Call& c) { return stop(c.api); }},
      {110, http::verb::post, "/api/abort", "safe state now, then end the campaign: {reason}", abort, {}, kAbortBody},
      {120,
       http::verb::post,
       "/api/inject/{kind}",
       "inject a gap change or a fault: gap, sensor, drive, rig, clear",
       inject,
       {},
       inject_fields()},
  };
}

}  // namespace hil::bench::api
