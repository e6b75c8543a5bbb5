// Fuzz target: one raw HTTP request to the bench server's API, answered as a connection would
// answer it (ApiServer::answer_raw: parser limits, Host and Origin, token, routes, campaign YAML and
// JSON bodies, their nesting and duplicate keys).
// A finding is a crash, a sanitizer report, a hang, or an answer that is not what its route gives
// (a JSON object; the console page or the token form as an HTML page; an empty 204) with a status
// the API documents; a 500 is a finding too (no input is the server's own fault).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string_view>

#include <boost/asio/io_context.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "hil/bench/server/runner.hpp"
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

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static Server server;
  const auto answer = server.api->answer_raw(std::string_view(reinterpret_cast<const char*>(data), size));
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
  const bool head_of_report = html && answer.body.empty() &&
                              std::string_view(reinterpret_cast<const char*>(data), size).find("HEAD") != std::string_view::npos;
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
  return 0;
}
