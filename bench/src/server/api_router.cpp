#include "api_router.hpp"

#include <algorithm>

#include <boost/beast/websocket.hpp>
#include <spdlog/spdlog.h>

namespace hil::bench {
namespace api {
namespace {

namespace websocket = beast::websocket;

// What GET / answers without a valid token: a form asking for it, nothing else. Submitting it
// loads /?token=T; a token this tab already gave (sessionStorage, set by the console) is offered
// again, so a reload of the console does not ask twice.
constexpr std::string_view kTokenForm = R"html(<!doctype html>
<html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width, initial-scale=1">
<title>hilbench: token</title><link rel="icon" href="data:,"></head>
<body style="font-family: sans-serif; margin: 3em auto; max-width: 28em">
<h1 style="font-size: 1.2em">hilbench operator console</h1>
<p>This bench server requires its token.</p>
<form method="get" action="/"><label>Token <input name="token" type="password" autocomplete="off" autofocus required></label>
<button type="submit">Open</button></form>
<script>
const kept = sessionStorage.getItem("hilbench.token");
if (kept && !new URLSearchParams(location.search).has("token")) location.replace("/?token=" + encodeURIComponent(kept));
</script>
</body></html>
)html";

// The route's path segments, or nothing when `path` is not its shape; "{name}" segments are
// collected into args.
bool match(std::string_view pattern, const std::vector<std::string>& path, std::vector<std::string>& args) {
  args.clear();
  if (pattern == "/") return path.empty();
  std::size_t i = 0;
  for (std::size_t from = 1; from <= pattern.size(); ++i) {
    const std::size_t to = std::min(pattern.find('/', from), pattern.size());
    const std::string_view seg = pattern.substr(from, to - from);
    if (i >= path.size()) return false;
    if (seg.size() > 1 && seg.front() == '{') {
      args.push_back(path[i]);
    } else if (seg != path[i]) {
      return false;
    }
    from = to + 1;
  }
  return i == path.size();
}

std::string route_list() {
  std::string out;
  for (const auto& r : routes()) {
    if (!out.empty()) out += ", ";
    out += std::string(http::to_string(r.method)) + " " + std::string(r.path);
  }
  return out;
}

}  // namespace

const std::vector<Route>& routes() {
  static const std::vector<Route> table = [] {
    std::vector<Route> all;
    for (auto* part :
         {server_routes, config_routes, control_routes, run_routes, analysis_routes, telemetry_routes, telemetry_range_routes}) {
      for (auto& r : part()) all.push_back(std::move(r));
    }
    std::stable_sort(all.begin(), all.end(), [](const Route& a, const Route& b) { return a.place < b.place; });
    return all;
  }();
  return table;
}

Fields Call::body() const { return Fields(parse_json_body(req), route.body); }

namespace {

std::vector<std::string> query_names(const Route& r) {
  std::vector<std::string> names;
  for (const auto& q : r.query) names.push_back(q.name);
  return names;
}

}  // namespace

Reply route_index() {
  json list = json::array();
  for (const auto& r : routes()) {
    list.push_back({{"method", std::string(http::to_string(r.method))},
                    {"path", std::string(r.path)},
                    {"summary", std::string(r.summary)},
                    {"query", query_names(r)}});
  }
  return json_reply(http::status::ok, {{"endpoints", list}});
}

// The row of `pattern` (one that is there: a programming error otherwise).
const Route& route_of(std::string_view pattern) {
  for (const auto& r : routes()) {
    if (r.path == pattern) return r;
  }
  throw std::logic_error("no route " + std::string(pattern));
}

// A query option the route does not take is refused by name, as an unknown body field is: ignored,
// a typo (?wiat=0, ?rate=5000, ?run=) did what was not asked without a word. So is one given twice
// (?rate_hz=1&rate_hz=5000 streamed at the last one). One check for every route, the telemetry

void refuse_unknown_query(const Target& t, const Route& r) {
  if (!t.repeated.empty()) {
    const std::string shown = loggable_target(t.repeated.front());
    throw ApiError{http::status::bad_request, "query option given twice", "'" + shown + "' is given more than once", shown};
  }
  std::vector<std::string> names = query_names(r);
  names.emplace_back("token");
  std::string takes;
  for (const auto& q : r.query) takes += q.name + ", ";
  const std::string after = "; " + std::string(r.path) + " takes " +
                            (takes.empty() ? "no query option" : takes.substr(0, takes.size() - 2)) + " (and token)";
  for (const auto& item : t.query) refuse_unknown(item.first, loggable_target(item.first), names, "unknown query option", after);
}

}  // namespace api

using namespace api;

// A request whose Host or Origin is not this server's (DNS rebinding, a page of another site):
// its refusal, said in the log. Checked before the token and the route, on every request.
std::optional<Reply> ApiServer::Impl::refused_header(const Request& req) const {
  if (!guard) return std::nullopt;
  const auto host = req[http::field::host];
  const auto origin = req[http::field::origin];
  const auto refusal = guard->check(std::string_view(host.data(), host.size()), req.count(http::field::host),
                                    std::string_view(origin.data(), origin.size()), req.count(http::field::origin));
  if (!refusal) return std::nullopt;
  spdlog::warn("{} {}: refused: {} ({})", std::string(req.method_string()), loggable_target(req.target()), refusal->error,
               refusal->header);
  return error_reply(static_cast<http::status>(refusal->status), refusal->error, refusal->detail, refusal->header);
}

bool ApiServer::Impl::authorised(const Request& req, const Target& t) const {
  if (options.token.empty()) return true;
  const auto field = req[http::field::authorization];
  std::string_view auth(field.data(), field.size());
  // RFC 9110 11.1: the scheme is case-insensitive ("bearer", "BEARER"), and one or more spaces
  // part it from the credentials. The token itself is compared exactly, in constant time.
  constexpr std::string_view bearer = "bearer";
  if (auth.size() > bearer.size() &&
      beast::iequals(field.substr(0, bearer.size()), beast::string_view(bearer.data(), bearer.size())) &&
      auth[bearer.size()] == ' ') {
    auth.remove_prefix(bearer.size());
    while (!auth.empty() && auth.front() == ' ') auth.remove_prefix(1);
    if (!auth.empty() && constant_time_equal(auth, options.token)) return true;
  }
  // Browsers cannot set headers on a WebSocket: the query may carry it.
  const auto q = t.query.find("token");
  return q != t.query.end() && constant_time_equal(q->second, options.token);
}

bool ApiServer::Impl::answered_on_worker(const Request& req, const Target& t) const {
  if (req.body().size() > kIoThreadBodyBytes) return true;
  std::vector<std::string> args;
  for (const auto& r : routes()) {
    const bool head_of_get = req.method() == http::verb::head && r.method == http::verb::get;
    if ((r.method == req.method() || head_of_get) && match(r.path, t.path, args)) return r.thread == Thread::worker;
  }
  return false;  // no route: the 404 or 405 is answered at once
}

Reply ApiServer::Impl::handle(const Request& req, const Target& t) {
  std::vector<std::string> args;
  std::string allow;  // the methods the path takes, for a 405
  for (const auto& r : routes()) {
    if (!match(r.path, t.path, args)) continue;
    // HEAD is GET without the body (RFC 9110 9.3.2): the same route, the same header fields.
    const bool head_of_get = req.method() == http::verb::head && r.method == http::verb::get;
    if (r.method == req.method() || head_of_get) {
      refuse_unknown_query(t, r);
      return r.handle(Call{*this, req, t, args, r});
    }
    allow += (allow.empty() ? "" : ", ") + std::string(http::to_string(r.method));
    if (r.method == http::verb::get) allow += ", HEAD";
  }
  if (!allow.empty()) {
    throw ApiError{http::status::method_not_allowed, "method not allowed",
                   std::string(req.method_string()) + " " + loggable_target(req.target()) + ": use " + allow, "", allow};
  }
  if (t.path.empty() || t.path[0] != "api")
    throw ApiError{http::status::not_found, "not found", "the API lives under /api (see GET /api)"};
  throw ApiError{http::status::not_found, "not found",
                 loggable_target(req.target()) + " is no endpoint; see GET /api: " + route_list()};
}

Reply ApiServer::Impl::answer(const Request& req, const Target& t) {
  Reply reply;
  if (!authorised(req, t)) {
    spdlog::warn("{} {}: refused (no valid token)", std::string(req.method_string()), loggable_target(req.target()));
    // A page asks for the token; a WebSocket handshake to / is refused in JSON like any other.
    if (t.path.empty() && req.method() == http::verb::get && !websocket::is_upgrade(req)) {
      Reply r = body_reply(http::status::unauthorized, std::string(kTokenForm), "text/html; charset=utf-8");
      r.no_store = true;
      return r;
    }
    return error_reply(http::status::unauthorized, "unauthorized",
                       "this server requires 'Authorization: Bearer <token>' on every request");
  }
  if (options.on_request) options.on_request();
  if (websocket::is_upgrade(req)) {
    reply = error_reply(http::status::bad_request, "WebSocket upgrade not possible here", "connect to /api/telemetry over TCP");
  } else {
    try {
      reply = handle(req, t);
    } catch (const ApiError& e) {
      reply = error_reply(e);
    } catch (const std::exception& e) {
      spdlog::error("{} {}: {}", std::string(req.method_string()), loggable_target(req.target()), e.what());
      reply = error_reply(http::status::internal_server_error, "internal error", e.what());
    }
  }
  if (static_cast<int>(reply.status) >= 400) {
    spdlog::info("{} {} -> {}", std::string(req.method_string()), loggable_target(req.target()), static_cast<int>(reply.status));
  }
  return reply;
}

Reply ApiServer::Impl::parse_failure(const beast::error_code& ec) const {
  if (ec == http::error::body_limit) {
    return error_reply(http::status::payload_too_large, "request body too large",
                       "the limit is " + std::to_string(options.max_body_bytes) + " bytes");
  }
  if (ec == http::error::header_limit) return error_reply(http::status::request_header_fields_too_large, "headers too large");
  return error_reply(http::status::bad_request, "malformed HTTP request", ec.message());
}

}  // namespace hil::bench
