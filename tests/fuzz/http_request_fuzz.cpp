// Fuzz target: one raw HTTP request to the bench server's API, answered as a connection would
// answer it (ApiServer::answer_raw: parser limits, Host and Origin, token, routes, campaign YAML and
// JSON bodies, their nesting and duplicate keys). The same bytes also choose a request from the
// route table (api_router.hpp): a route, its "{name}" segments, its declared query options and
// body fields with values of the declared type or another, and now and then a name it does not
// declare; such a request must never be accepted (2xx) with a body field its route does not take.
// A finding is a crash, a sanitizer report, a hang, or an answer that is not what its route gives
// (a JSON object; the console page or the token form as an HTML page; an empty 204) with a status
// the API documents; a 500 is a finding too (no input is the server's own fault).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string_view>

#include <boost/asio/io_context.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "hil/bench/server/runner.hpp"
#include "server/api_router.hpp"
#include "server/api_server.hpp"

namespace {

struct Server {
  boost::asio::io_context io;  // never run: answers come from answer_raw
  hil::bench::TelemetryHub hub;
  std::filesystem::path runs = std::filesystem::temp_directory_path() / ("hil_fuzz_runs_" + std::to_string(::getpid()));
  std::unique_ptr<hil::bench::CampaignRunner> runner;
  std::unique_ptr<hil::bench::ApiServer> api;
  Server() {
    spdlog::set_level(spdlog::level::off);
    hil::bench::RunnerOptions ro;
    ro.runs_dir = runs;
    runner = std::make_unique<hil::bench::CampaignRunner>(std::move(ro));
    hil::bench::ApiOptions o;
    o.port = 0;
    o.campaigns_dir = std::filesystem::path(HIL_SOURCE_DIR) / "configs/campaigns";
    o.rigs_dir = std::filesystem::path(HIL_SOURCE_DIR) / "configs/rigs";
    o.plant_dir = std::filesystem::path(HIL_SOURCE_DIR) / "configs/plant";
    o.runs_dir = runs;
    o.max_body_bytes = 64 * 1024;
    // The corpus's requests say "Host: x" (port 80): allowed, so that they reach the routes; any
    // other Host or Origin the fuzzer makes meets the DNS-rebinding check (403/400, JSON).
    o.allow_hosts = {"x:80"};
    api = std::make_unique<hil::bench::ApiServer>(io, o, *runner, hub);
  }
  ~Server() {
    api.reset();
    runner.reset();
    std::error_code ec;
    std::filesystem::remove_all(runs, ec);
  }
};

// The bytes, read one value at a time (zeros once they are used up).
class Bytes {
 public:
  Bytes(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  std::uint8_t byte() { return at_ < size_ ? data_[at_++] : 0; }
  std::string text() {
    const std::size_t n = std::min<std::size_t>(byte() % 12, size_ - std::min(at_, size_));
    std::string out(reinterpret_cast<const char*>(data_ + at_), n);
    at_ += n;
    return out;
  }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t at_ = 0;
};

// A value for a field of `type`: of that type (sometimes at or past its range), or of another.
nlohmann::json value_for(hil::bench::api::FieldType type, const hil::bench::api::FieldSpec& spec, Bytes& in) {
  using hil::bench::api::FieldType;
  const std::uint8_t pick = in.byte();
  if (pick % 5 == 4) {  // the wrong type
    switch (in.byte() % 4) {
      case 0: return in.text();
      case 1: return static_cast<int>(in.byte()) - 128;
      case 2: return nullptr;
      default: return nlohmann::json::array({in.text()});
    }
  }
  switch (type) {
    case FieldType::text: return in.text();
    case FieldType::flag: return (pick & 1) != 0;
    case FieldType::text_list: return nlohmann::json::array({in.text(), in.text()});
    case FieldType::number:
    case FieldType::whole: {
      const double v = pick % 3 == 0 ? spec.min : pick % 3 == 1 ? spec.max : static_cast<int>(in.byte()) - 100;
      return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(static_cast<int>(in.byte()));
    }
  }
  return nullptr;
}

// The fuzzer's text is any bytes: a value that is no UTF-8 is written with U+FFFD, as the
// server's own replies are (dump_json), instead of throwing in the harness.
std::string query_value(const hil::bench::api::FieldSpec& spec, Bytes& in) {
  const nlohmann::json v = value_for(spec.type, spec, in);
  return v.is_string() ? v.get<std::string>() : v.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

// A request built from the route table; `unknown_field`: its body carries a name its route does
// not declare.
std::string table_request(Bytes& in, bool& unknown_field) {
  const auto& routes = hil::bench::api::routes();
  const auto& route = routes[in.byte() % routes.size()];
  std::string target;
  for (std::size_t from = 1; from <= route.path.size();) {
    const std::size_t to = std::min(route.path.find('/', from), route.path.size());
    const std::string_view seg = route.path.substr(from, to - from);
    if (!seg.empty()) target += "/" + (seg.front() == '{' ? (in.byte() % 2 ? std::string("x") : in.text()) : std::string(seg));
    from = to + 1;
  }
  if (target.empty()) target = "/";
  char sep = '?';
  for (const auto& q : route.query) {
    if (in.byte() % 2) continue;
    target += sep + q.name + "=" + query_value(q, in);
    sep = '&';
  }
  nlohmann::json body = nlohmann::json::object();
  for (const auto& f : route.body) {
    if (in.byte() % 3 != 0) body[f.name] = value_for(f.type, f, in);
  }
  unknown_field = !route.body.empty() && in.byte() % 7 == 0;
  if (unknown_field) body["not_" + in.text()] = 1;
  const std::string text = body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  std::string clean;
  for (const char ch : target) {  // a request line is printable ASCII; the rest stays as it came
    const auto c = static_cast<unsigned char>(ch);
    static constexpr char kHex[] = "0123456789ABCDEF";
    if (c > 0x20 && c < 0x7f) {
      clean.push_back(ch);
    } else {
      clean += {'%', kHex[c >> 4], kHex[c & 15]};
    }
  }
  return std::string(boost::beast::http::to_string(route.method)) + " " + clean +
         " HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: " + std::to_string(text.size()) + "\r\n\r\n" +
         text;
}

// One request's answer, checked against what its route gives.
hil::bench::ApiServer::RawAnswer check(Server& server, std::string_view request) {
  const auto answer = server.api->answer_raw(request);
  // A start that got through runs a real campaign: end it at once, so inputs stay independent.
  if (server.runner->running()) {
    try {
      server.runner->abort("fuzz input done");
    } catch (const hil::bench::Conflict&) {}
    server.runner->wait();
  }
  if (answer.status >= 500 || answer.status < 200) {
    std::fprintf(stderr, "answered %d: %s\n", answer.status, answer.body.c_str());
    std::abort();
  }
  // The API answers JSON; the console page and the token form are HTML pages, the icon an empty 204.
  const bool file = answer.body.rfind("file: ", 0) == 0;  // streamed from disk (a run's file or report)
  const bool html = answer.content_type.rfind("text/html", 0) == 0;
  // HEAD of a run's report not made yet: the page's header alone, for a report HEAD does not make.
  const bool head_of_report = html && answer.body.empty() && request.find("HEAD") != std::string_view::npos;
  if (html && !file && !head_of_report && answer.body.rfind("<!doctype html>", 0) != 0) {
    std::fprintf(stderr, "answered %d with text/html that is not a page: %s\n", answer.status, answer.body.c_str());
    std::abort();
  }
  const bool json_expected = !html && !file && answer.status != 204;
  if (answer.status == 204 && !answer.body.empty()) {
    std::fprintf(stderr, "answered 204 with a body: %s\n", answer.body.c_str());
    std::abort();
  }
  if (json_expected) {
    const auto j = nlohmann::json::parse(answer.body, nullptr, /*allow_exceptions=*/false);
    if (!j.is_object()) {
      std::fprintf(stderr, "answered %d with no JSON object: %s\n", answer.status, answer.body.c_str());
      std::abort();
    }
  }
  return answer;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static Server server;
  check(server, std::string_view(reinterpret_cast<const char*>(data), size));
  Bytes in(data, size);
  bool unknown_field = false;
  const std::string request = table_request(in, unknown_field);
  const auto answer = check(server, request);
  if (unknown_field && answer.status < 300) {
    std::fprintf(stderr, "a body field its route does not declare was accepted (%d): %s\n", answer.status, request.c_str());
    std::abort();
  }
  return 0;
}
