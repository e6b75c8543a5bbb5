// The API server's shared state (ApiServer::Impl): what the listener, the HTTP sessions, the
// router and the resources' handlers all reach. The handlers are free functions of their
// resource's file (routes_*.cpp); what they share of a run folder is in api_run_files.hpp.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/thread_pool.hpp>

#include "api_reply.hpp"
#include "api_server.hpp"
#include "hil/config_files.hpp"
#include "jobs.hpp"
#include "request_guard.hpp"

namespace hil::bench {

namespace api {
class HttpSession;
}

struct ApiServer::Impl : std::enable_shared_from_this<ApiServer::Impl> {
  Impl(boost::asio::io_context& io_, ApiOptions o, CampaignRunner& r, TelemetryHub& h);

  boost::asio::io_context& io;
  ApiOptions options;
  CampaignRunner& runner;
  TelemetryHub& hub;
  boost::asio::ip::tcp::acceptor acceptor;
  // Why new campaigns and jobs are refused (shutting down), or empty; read on the io thread and on
  // the request worker (start, start_analysis).
  std::string refusing() const {
    std::lock_guard lock(refuse_mutex);
    return refuse_starts;
  }
  mutable std::mutex refuse_mutex;
  std::string refuse_starts;  // under refuse_mutex
  // The request worker: the thread that answers the routes that read files or parse what a client
  // posted (api_router.hpp Thread::worker: /api/start, the config listings, everything under
  // /api/runs) and every request with a body over kIoThreadBodyBytes, so that the io thread that
  // answers status, stop, abort and the telemetry streams never waits behind them (a run.json
  // nested 20 000 deep held them all for 7 s, a 9 000-check campaign 22 s). One thread: the checks
  // and submits of jobs (run_report, start_analysis) keep one order. Its queue holds at most one
  // request per open connection (a session reads its next request once the last is answered);
  // a request that waited kWorkerWaitBudget for it is answered 503 without being worked on.
  // Joined by ~ApiServer.
  boost::asio::thread_pool worker{1};
  static constexpr std::chrono::seconds kWorkerWaitBudget{15};
  std::shared_ptr<std::atomic<int>> open_connections = std::make_shared<std::atomic<int>>(0);
  std::shared_ptr<std::atomic<int>> open_streams = std::make_shared<std::atomic<int>>(0);  // telemetry WebSockets
  std::chrono::steady_clock::time_point last_stream_refusal_logged{};                      // io thread only
  std::chrono::steady_clock::time_point last_refusal_logged{};                             // io thread only
  // The HTTP sessions, for evicting the longest-idle one when the connections are at their cap
  // (io thread only; expired ones are pruned there).
  std::vector<std::weak_ptr<api::HttpSession>> http_sessions;
  JobQueue jobs;                 // submitted to on the io thread only: a check and its submit never race
  const std::string session_id;  // Foxglove's serverInfo.sessionId (api_listener.cpp new_session_id)
  // The entry of each config file in GET /api/campaigns, /api/rigs and /api/models, with the files
  // its load read (a rig's device files and register maps, a campaign's plant and CSV reference):
  // parsed again only when one of them has changed (routes_configs.cpp).
  struct Listing {
    nlohmann::json entry;
    std::vector<cfg::FileStamp> files;
  };
  using Listings = std::map<std::string, Listing>;           // by the file's stem
  Listings campaign_listings, rig_listings, model_listings;  // the request worker's only

  // The listener (api_listener.cpp).
  void accept();
  bool evict_longest_idle();

  // The router (api_router.cpp).
  bool authorised(const api::Request& req, const api::Target& t) const;
  // Host and Origin against the names this server answers (request_guard.hpp): the refusal, or nothing.
  std::optional<api::Reply> refused_header(const api::Request& req) const;
  std::optional<HostGuard> guard;  // set once the port is bound
  // Whether the request is answered on the request worker (its route's Thread, or its body's size).
  bool answered_on_worker(const api::Request& req, const api::Target& t) const;
  // A parsed request's answer: authorisation, the route, errors as replies, the log line.
  api::Reply answer(const api::Request& req, const api::Target& t);
  // The answer to a request the HTTP parser refused.
  api::Reply parse_failure(const boost::beast::error_code& ec) const;
  api::Reply handle(const api::Request& req, const api::Target& t);
};

}  // namespace hil::bench
