// The operator API of `hilbench serve`: HTTP/JSON and a WebSocket telemetry stream on
// Boost.Beast, served by one io_context thread. Endpoints: see bench/SERVER.md.
// Requests never wait for the loop: they read the runner's status and hand requests over. Reports
// and analyses of recorded runs run on the server's job worker (jobs.hpp), never on the io thread.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <nlohmann/json.hpp>

#include "hil/bench/server/runner.hpp"

namespace hil::bench {

struct ApiOptions {
  std::string address = "127.0.0.1";
  unsigned short port = 8470;  // 0: any free port (see ApiServer::port)
  std::string token;           // when set, every request must carry it
  std::filesystem::path campaigns_dir = "configs/campaigns";
  std::filesystem::path rigs_dir = "configs/rigs";
  std::filesystem::path runs_dir = "runs";
  std::filesystem::path plant_dir = "configs/plant";  // the models analyses may name
  std::size_t max_body_bytes = 1 << 20;
  std::size_t max_waiting_jobs = 8;  // reports and analyses queued behind the running one
  // A diagnosis that would hold more (analyses.hpp diagnose_memory_bytes) is refused (422): the
  // server's memory is locked, and a bench machine out of memory kills the server mid-run.
  std::uint64_t max_diagnose_bytes = UINT64_MAX;
  // Host names the server answers besides its listen address and the loopback names (--allow-host
  // NAME or NAME:PORT; request_guard.hpp): a foreign Host or Origin is refused 403.
  std::vector<std::string> allow_hosts;
  // A telemetry WebSocket from which nothing was received for this long is closed; the server
  // pings it at half this time, and a client that reads answers the ping (--ws-idle-timeout-s).
  std::chrono::milliseconds ws_idle_timeout = std::chrono::seconds(300);
  std::string version;
  // Called on every authorised request (any thread): the operator link hears its clients
  // (operator_link.hpp).
  std::function<void()> on_request;
};

class WsSession;

// Fans telemetry out to WebSocket clients, each decimated to the rate it asked for. publish_*
// may be called from any thread (the recorder's, the runner's) and only queue what they are
// given: the fan-out runs on the hub's own thread, which hands each session its messages of a
// round in one handler on the io thread. The recorder thread must never pay for the watchers:
// a row per session per period cost it the time to drain the loop's ring, and 250 clients that
// never read made a 10 kHz run lose rows and abort. What the hub cannot take (its queue full) is
// lost for the stream only, counted, and said in the log; telemetry.csv is the record.
class TelemetryHub {
 public:
  TelemetryHub();
  ~TelemetryHub();  // stop()
  TelemetryHub(const TelemetryHub&) = delete;
  TelemetryHub& operator=(const TelemetryHub&) = delete;

  void publish_row(const TelemetryRecord& r);
  void publish_notice(const nlohmann::json& j);
  // The bench's state (status_stream.hpp), to the plain JSON clients only (Foxglove clients have
  // their own status channel), without resetting their decimation; taken even when the inbox is
  // full of rows: the state of the bench is what an operator may not miss.
  void publish_status(const nlohmann::json& j);
  // foxglove: the session speaks foxglove.websocket.v1 (binary frames per channel), else the
  // JSON rows of bench/SERVER.md.
  void subscribe(const std::shared_ptr<WsSession>& s, double rate_hz, bool foxglove);
  void unsubscribe(const WsSession* s);
  std::size_t subscribers() const;
  // Ends the fan-out thread (what is queued is dropped). Before the io_context the sessions post
  // to is destroyed; idempotent.
  void stop();

 private:
  struct Sub {
    std::weak_ptr<WsSession> session;
    const WsSession* key;
    double interval_s;
    double next_t_s;
    bool foxglove;
    double held_comp_rad = 0;  // the largest compensation jump of the rows this client skipped
  };
  struct Item {  // a row, or a notice when `notice` is set
    TelemetryRecord row;
    std::shared_ptr<const nlohmann::json> notice;
    bool status = false;  // publish_status's
  };
  static constexpr std::size_t kInboxItems = 16384;  // 1.6 s of a 10 kHz loop
  void enqueue(Item item);                           // any thread: a lock and a move, never a wait
  void fan_out_loop();
  void fan_out(const std::vector<Item>& items);

  mutable std::mutex mutex_;  // subs_, last_t_s_
  std::vector<Sub> subs_;
  double last_t_s_ = 0;  // of the last row fanned out: the time stamp of a notice without one

  std::mutex inbox_mutex_;
  std::condition_variable inbox_cv_;
  std::vector<Item> inbox_;
  std::uint64_t inbox_dropped_ = 0;  // rows and notices the stream lost to a full inbox
  bool stop_ = false;
  std::thread thread_;
};

class ApiServer {
 public:
  // Binds and starts accepting. Throws when the address cannot be bound, or when it is not a
  // loopback address and no token is set.
  ApiServer(boost::asio::io_context& io, ApiOptions options, CampaignRunner& runner, TelemetryHub& hub);
  ~ApiServer();
  ApiServer(const ApiServer&) = delete;
  ApiServer& operator=(const ApiServer&) = delete;

  unsigned short port() const;
  bool loopback() const { return loopback_; }
  void refuse_starts(const std::string& why);  // shutting down: new campaigns get 503

  // Ends the report and analysis jobs: the queued ones fail, the running one is waited for (it
  // stops at its next cancel point, failed "server stopped": an analysis at its next chunk or fit,
  // a report at its next chunk of rows). The destructor does it too.
  void stop_jobs();
  // The same without waiting (a signal, on the io thread): the queued jobs fail, later ones are
  // refused, and the running one is asked to stop.
  void cancel_jobs();

  // One raw HTTP/1.1 request answered as a connection would answer it (parser limits, token,
  // routes, errors), without a socket: for the fuzz target. Call on the io thread, or with the
  // io_context not running. A WebSocket upgrade is answered 400.
  struct RawAnswer {
    int status;
    std::string body;
    std::string content_type;
  };
  RawAnswer answer_raw(std::string_view bytes);

  struct Impl;

 private:
  std::shared_ptr<Impl> impl_;
  bool loopback_ = true;
};

}  // namespace hil::bench
