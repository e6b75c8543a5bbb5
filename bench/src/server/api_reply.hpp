// What every part of the API server shares: a request's target taken apart, an answer (Reply),
// the error a handler throws (ApiError) and the one conversion of it into an answer. The parts:
// the listener (api_server.cpp, api_listener.cpp), the HTTP session (api_http_session.*), the
// router (api_router.*), the request fields (api_fields.*), the resources' routes (routes_*.cpp)
// and the telemetry stream (telemetry_stream.*).
#pragma once

#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <boost/beast/http.hpp>
#include <nlohmann/json.hpp>

#include "jobs.hpp"

namespace hil::bench::api {

namespace beast = boost::beast;
namespace http = beast::http;
using nlohmann::json;
using Request = http::request<http::string_body>;

struct Reply;

// An answer that waits for a job: the connection sends `then(final state)` once the job has
// finished, without holding the io thread meanwhile. Without a connection (answer_raw) the reply's
// own body (202, the job's state) is the answer.
struct JobWait {
  std::string run, id;
  std::function<Reply(const JobStatus&)> then;
};

// An answer: JSON (or text) in memory, or a file streamed from disk.
struct Reply {
  http::status status = http::status::ok;
  std::string body;
  std::string content_type = "application/json";
  std::filesystem::path file;                     // non-empty: send this file (its name, for answer_raw and the log)
  std::shared_ptr<const int> fd = nullptr;        // with `file`: the file, opened without following a link (open_inside)
  std::string extra_header;                       // Content-Disposition for downloads
  bool no_store = false;                          // Cache-Control: no-store (the console: a new build is a new page)
  std::string allow;                              // Allow, on a 405
  bool length_unknown = false;                    // a HEAD's answer for a body not made: no Content-Length at all
  std::shared_ptr<const JobWait> wait = nullptr;  // set: the final answer comes when the job has finished
};

// Text from a request (a path, a query, a parser's message quoting the body) may hold bytes
// that are not UTF-8; dumping them must not throw, so they become U+FFFD.
std::string dump_json(const json& j, int indent = -1);

// An answer held in memory (Reply's other members at their defaults).
Reply body_reply(http::status status, std::string body, std::string content_type);
Reply json_reply(http::status status, const json& j);
Reply error_reply(http::status status, const std::string& error, const std::string& detail = "", const std::string& field = "");

// Thrown inside a handler: becomes an error reply.
struct ApiError {
  http::status status;
  std::string error, detail;
  std::string field = {};  // the body field at fault, where one is
  std::string allow = {};  // a 405's Allow header: the methods the path takes (RFC 9110 15.5.6)
};

// The answer an ApiError stands for, its Allow header included: one conversion for every place
// that catches one.
Reply error_reply(const ApiError& e);

struct Target {
  std::vector<std::string> path;  // "/api/runs/x" -> {"api", "runs", "x"}
  std::map<std::string, std::string> query;
  std::vector<std::string> repeated;  // query options given more than once (refused: which one was meant?)
};

Target parse_target(std::string_view target);

// A request target as it may appear in the server log or an error reply: a token in the query is replaced, and
// bytes outside printable ASCII are escaped, so the log neither leaks a secret nor holds raw
// control characters from a client.
std::string loggable_target(beast::string_view raw);

bool constant_time_equal(std::string_view a, std::string_view b);

// The names of dir/*.yaml, sorted.
std::vector<std::string> yaml_stems(const std::filesystem::path& dir);

}  // namespace hil::bench::api
