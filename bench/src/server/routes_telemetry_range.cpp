// GET /api/runs/{id}/telemetry?from_s=&to_s=&columns=: a time range of a run's telemetry.csv at
// full resolution (telemetry_range.hpp), what a served report fetches when it is zoomed in.
#include "api_router.hpp"
#include "api_run_files.hpp"
#include "hil/bench/server/runner.hpp"
#include "hil/telemetry_schema.hpp"
#include "request_guard.hpp"
#include "telemetry_range.hpp"

namespace hil::bench::api {
namespace {

const FieldSpecs kRangeQuery = {
    {"from_s", FieldType::number, "s", -1.0e9, 1.0e9, false, "the range's first time (t_s of the run)"},
    {"to_s", FieldType::number, "s", -1.0e9, 1.0e9, false, "the range's last time"},
    {"columns", FieldType::text, "", -INFINITY, INFINITY, false, "telemetry columns, comma-separated (t_s is always given)"},
    {"max_rows", FieldType::whole, "rows", 1, static_cast<double>(kTelemetryRangeMaxRows), false,
     "refuse a range holding more rows than this (20000 when not given)"}};

Reply telemetry_range(const Call& c) {
  const ApiServer::Impl& api = c.api;
  const std::string& id = c.args[0];
  require_run(api, id);
  for (const char* needed : {"from_s", "to_s", "columns"}) {
    if (!c.target.query.count(needed))
      throw ApiError{http::status::bad_request, "missing field", std::string("'") + needed + "' is required", needed};
  }
  TelemetryRange q;
  q.from_s = query_number(c.target, spec_of(c.route.query, "from_s"), 0);
  q.to_s = query_number(c.target, spec_of(c.route.query, "to_s"), 0);
  q.max_rows = static_cast<std::uint64_t>(query_number(c.target, spec_of(c.route.query, "max_rows"), 20000));
  if (!(q.to_s >= q.from_s)) throw ApiError{http::status::bad_request, "bad field", "'to_s' must not be before 'from_s'", "to_s"};
  const std::string& list = c.target.query.at("columns");
  for (std::size_t b = 0; b <= list.size();) {
    const auto e = std::min(list.find(',', b), list.size());
    if (e > b) q.columns.push_back(list.substr(b, e - b));
    b = e + 1;
  }
  if (q.columns.size() > telemetry::kColumns.size() * 2)
    throw ApiError{http::status::bad_request, "bad field", "'columns' names more columns than a telemetry row has", "columns"};
  const RunFile f = open_run_file(
      api.options.runs_dir, {id, "telemetry.csv"},
      "run '" + id + "' has no telemetry.csv (the range is read from it; a run that kept only telemetry.mcap has none)");
  try {
    return body_reply(http::status::ok, telemetry_range_json(*f.fd, f.size, id + "/telemetry.csv", q), "application/json");
  } catch (const BadField& e) {
    throw ApiError{http::status::bad_request, "bad field", e.what(), e.field};
  } catch (const std::runtime_error& e) {
    throw ApiError{http::status::unprocessable_entity, "file not read", e.what()};
  }
}

}  // namespace

std::vector<Route> telemetry_range_routes() {
  return {{205,
           http::verb::get,
           "/api/runs/{id}/telemetry",
           "a time range of a run's telemetry.csv at full resolution: ?from_s=&to_s=&columns=a,b (at most ?max_rows=, 20000 "
           "when not given), as JSON arrays",
           telemetry_range,
           kRangeQuery,
           {},
           Thread::worker}};
}

}  // namespace hil::bench::api
