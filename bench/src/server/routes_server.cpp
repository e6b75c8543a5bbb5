// The server's own routes: the console page, the icon, the route index and health.
#include "api_router.hpp"
#include "console/assets.hpp"

namespace hil::bench::api {

std::vector<Route> server_routes() {
  return {
      {10, http::verb::get, "/", "the operator console: live plots, loop health, events, controls, runs (HTML)",
       [](const Call&) {
         Reply r = body_reply(http::status::ok, std::string(console::kPage), "text/html; charset=utf-8");
         r.no_store = true;
         return r;
       }},
      {20, http::verb::get, "/favicon.ico", "no icon: 204, so that a browser asking for one is not an error",
       [](const Call&) { return body_reply(http::status::no_content, "", "image/x-icon"); }},
      {30, http::verb::get, "/api", "this list", [](const Call&) { return route_index(); }},
      {40, http::verb::get, "/api/health", "the server answers, and its version",
       [](const Call& c) {
         return json_reply(http::status::ok, {{"ok", true}, {"version", c.api.options.version}});
       }},
  };
}

}  // namespace hil::bench::api
