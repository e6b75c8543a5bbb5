// The router: the route table (each resource's file contributes its rows), matching a request's
// path and method to a row, authorisation, and errors as replies. A row declares its query options
// and its JSON body's fields (api_fields.hpp): GET /api lists the table, the one validator reads a
// request against its row, and the fuzz target (tests/fuzz/http_request_fuzz.cpp) builds requests
// from it.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "api_fields.hpp"
#include "api_impl.hpp"

namespace hil::bench::api {

struct Route;

// What a handler is given: the server, the request, its target, the "{name}" segments of its
// path in order, and its route's row.
struct Call {
  ApiServer::Impl& api;
  const Request& req;
  const Target& target;
  const std::vector<std::string>& args;
  const Route& route;
  // The JSON body read against the route's body fields (unknown names refused at once).
  Fields body() const;
};

// Where a route is answered. The io thread serves status, stop, abort, the injections and the
// telemetry streams, and must never wait: a route that reads files or parses what a client sent
// (a campaign, a rig, its checks, every run folder's file) is answered on the request worker
// (ApiServer::Impl::worker), and so is any request whose body is larger than kIoThreadBodyBytes.
enum class Thread { io, worker };

// The largest body a request answered on the io thread may have; a larger one is parsed on the
// request worker (a 700 KB campaign posted to /api/start held abort for 22 s on the io thread).
inline constexpr std::size_t kIoThreadBodyBytes = 8 * 1024;

// One endpoint: the method, the path ("{name}" matches one segment, handed to the handler in
// order), what it does (GET /api lists this table), the handler, the query options it takes
// (`token`, authorised(), is every route's) and its body's fields. `place` orders the table: GET
// /api lists it in that order, and a path is matched against the rows in it (a literal segment
// before a "{name}" at the same place: /api/runs/{id}/events before /api/runs/{id}/{file}), and the
// thread it is answered on.
struct Route {
  int place;
  http::verb method;
  std::string_view path;
  std::string_view summary;
  Reply (*handle)(const Call& call);
  FieldSpecs query = {};
  FieldSpecs body = {};
  Thread thread = Thread::io;
};

// Each resource's rows (routes_*.cpp, telemetry_stream.cpp).
std::vector<Route> server_routes();  // the console page, the icon, the index, health
std::vector<Route> config_routes();
std::vector<Route> control_routes();
std::vector<Route> run_routes();
std::vector<Route> analysis_routes();
std::vector<Route> telemetry_routes();
std::vector<Route> telemetry_range_routes();  // routes_telemetry_range.cpp

// The whole table, in place order.
const std::vector<Route>& routes();

// The row of `pattern` (one that is there: a programming error otherwise).
const Route& route_of(std::string_view pattern);

// A query option the route does not take is refused by name, as an unknown body field is: ignored,
// a typo (?wiat=0, ?rate=5000, ?run=) did what was not asked without a word. So is one given twice
// (?rate_hz=1&rate_hz=5000 streamed at the last one). One check for every route, the telemetry
// WebSocket's included.
void refuse_unknown_query(const Target& t, const Route& r);

// GET /api: the table.
Reply route_index();

}  // namespace hil::bench::api
