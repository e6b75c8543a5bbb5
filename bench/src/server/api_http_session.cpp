#include "api_http_session.hpp"

#include <unistd.h>

#include <array>

#include <boost/asio/post.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <spdlog/spdlog.h>

#include "api_router.hpp"
#include "connection_slot.hpp"
#include "telemetry_stream.hpp"

namespace hil::bench::api {

namespace asio = boost::asio;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;

// ---------------------------------------------------------------------------------------------
// HTTP session.

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket&& socket, std::shared_ptr<ApiServer::Impl> api)
      : stream_(std::move(socket)), api_(std::move(api)), slot_(api_->open_connections) {}
  HttpSession(const HttpSession&) = delete;
  HttpSession& operator=(const HttpSession&) = delete;

  // Waiting for a request since when (nullopt: serving one, or closed): the connection to give up
  // first when the server is at its connection cap.
  std::optional<std::chrono::steady_clock::time_point> idle_since() const { return idle_since_; }
  // Ends the wait for a request (the connection's slot goes to a newcomer). Io thread.
  void evict() {
    if (!idle_since_) return;
    idle_since_.reset();
    stream_.cancel();  // the pending read ends with operation_aborted, and the session closes
  }

  void read() {
    idle_since_ = std::chrono::steady_clock::now();
    parser_.emplace();
    parser_->body_limit(api_->options.max_body_bytes);
    parser_->header_limit(16 * 1024);
    stream_.expires_after(std::chrono::seconds(60));
    http::async_read(stream_, buffer_, *parser_,
                     [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_read(ec); });
  }

 private:
  void on_read(beast::error_code ec) {
    idle_since_.reset();
    if (ec == http::error::end_of_stream || ec == beast::error::timeout || ec == asio::error::connection_reset ||
        ec == asio::error::operation_aborted)
      return close();
    if (ec) {
      draining_ = ec == http::error::body_limit;  // read the rest of the body after answering, so the client sees the 413
      head_ = false;
      return send(api_->parse_failure(ec), false);
    }
    Request req = parser_->release();
    head_ = req.method() == http::verb::head;
    // One request's failure is that request's answer, never the server's end: a handler that
    // throws anything gets a 500 for this request, and a running campaign goes on.
    try {
      // Before the token and the route, for every request and the WebSocket upgrade.
      if (auto refused = api_->refused_header(req)) return send(std::move(*refused), false);
      const Target target = parse_target(std::string_view(req.target().data(), req.target().size()));
      if (websocket::is_upgrade(req) && api_->authorised(req, target)) return upgrade(std::move(req), target);
      if (!websocket::is_upgrade(req) && api_->answered_on_worker(req, target)) return answer_on_worker(std::move(req), target);
      Reply reply = api_->answer(req, target);
      // A refused upgrade ends the connection, as Beast's own refusals of a handshake do: the
      // client asked for a WebSocket, not for more HTTP on this connection.
      send(std::move(reply), req.keep_alive() && !websocket::is_upgrade(req));
    } catch (const std::exception& e) {
      spdlog::error("{} {}: {}", std::string(req.method_string()), loggable_target(req.target()), e.what());
      send(error_reply(http::status::internal_server_error, "internal error", e.what()), false);
    } catch (...) {
      spdlog::error("{} {}: unknown exception", std::string(req.method_string()), loggable_target(req.target()));
      send(error_reply(http::status::internal_server_error, "internal error"), false);
    }
  }

  // A request that reads files or parses a large body: answered on the request worker
  // (Impl::worker), sent from here. The connection waits; the io thread does not. One that waited
  // longer than the worker's budget for it is refused unread: its client has waited long enough
  // to be told, and the work behind it is not made longer.
  void answer_on_worker(Request req, const Target& target) {
    const bool keep_alive = req.keep_alive();
    auto asked = std::make_shared<const std::pair<Request, Target>>(std::move(req), target);
    const auto queued = std::chrono::steady_clock::now();
    asio::post(api_->worker, [self = shared_from_this(), asked, keep_alive, queued] {
      Reply reply;
      try {
        const auto waited = std::chrono::steady_clock::now() - queued;
        if (waited > ApiServer::Impl::kWorkerWaitBudget) {
          reply = error_reply(
              http::status::service_unavailable, "the server is busy",
              "this request waited " + std::to_string(std::chrono::duration_cast<std::chrono::seconds>(waited).count()) +
                  " s for the request worker (the limit is " + std::to_string(ApiServer::Impl::kWorkerWaitBudget.count()) +
                  " s) behind other requests that read files or parse campaigns; try again");
        } else {
          reply = self->api_->answer(asked->first, asked->second);
        }
      } catch (const std::exception& e) {
        spdlog::error("{} {}: {}", std::string(asked->first.method_string()), loggable_target(asked->first.target()), e.what());
        reply = error_reply(http::status::internal_server_error, "internal error", e.what());
      } catch (...) {
        reply = error_reply(http::status::internal_server_error, "internal error");
      }
      asio::post(self->stream_.get_executor(),
                 [self, reply = std::move(reply), keep_alive]() mutable { self->send(std::move(reply), keep_alive); });
    });
  }

  void upgrade(Request req, const Target& target) {
    if (target.path != std::vector<std::string>{"api", "telemetry"}) {
      return send(error_reply(http::status::not_found, "not found", "WebSocket endpoint is /api/telemetry"), false);
    }
    double rate_hz = 20;
    try {
      refuse_unknown_query(target, route_of("/api/telemetry"));
      rate_hz = telemetry_rate_hz(target);
    } catch (const ApiError& e) {
      return send(error_reply(e), false);
    }
    if (*api_->open_streams >= kMaxStreams) {
      const auto now = std::chrono::steady_clock::now();
      if (now - api_->last_stream_refusal_logged > std::chrono::minutes(1)) {
        spdlog::warn("{} telemetry streams are open: refusing more (503) until some close", kMaxStreams);
        api_->last_stream_refusal_logged = now;
      }
      return send(error_reply(http::status::service_unavailable, "too many telemetry streams",
                              std::to_string(kMaxStreams) +
                                  " telemetry streams are open, the most this server takes: the other connections are kept "
                                  "for the operator's requests (abort); try again when one has closed"),
                  false);
    }
    const bool foxglove = offers_foxglove(req);
    start_telemetry_stream(stream_.release_socket(), std::move(buffer_), api_->hub, foxglove, api_->session_id, std::move(slot_),
                           ConnectionSlot(api_->open_streams), api_->options.ws_idle_timeout, std::move(req), rate_hz);
  }

  void send(Reply reply, bool keep_alive) {
    if (reply.wait) {
      // The answer waits for a job: the io thread goes on serving; the job's end posts it here.
      const auto wait = std::move(reply.wait);
      const bool waiting =
          api_->jobs.when_finished(wait->run, wait->id, [self = shared_from_this(), wait, keep_alive](const JobStatus& s) {
            asio::post(self->stream_.get_executor(), [self, wait, s, keep_alive] {
              Reply r;
              try {
                r = wait->then(s);
              } catch (const std::exception& e) {
                r = error_reply(http::status::internal_server_error, "internal error", e.what());
              }
              self->stream_.expires_after(std::chrono::seconds(60));  // the read's deadline may have passed while waiting
              self->send(std::move(r), keep_alive);
            });
          });
      if (waiting) return;
    }
    if (!reply.file.empty()) {
      http::file_body::value_type body;
      beast::error_code ec;
      if (reply.fd && *reply.fd >= 0) {
        // The file opened when it was checked (opened_file), not the path again.
        beast::file file;
        file.native_handle(::dup(*reply.fd));
        if (file.native_handle() < 0) ec = beast::error_code(errno, beast::system_category());
        if (!ec) body.reset(std::move(file), ec);
      } else {
        body.open(reply.file.c_str(), beast::file_mode::scan, ec);
      }
      if (ec) return send(error_reply(http::status::internal_server_error, "cannot read file", ec.message()), keep_alive);
      auto res = std::make_shared<http::response<http::file_body>>(std::piecewise_construct, std::make_tuple(std::move(body)),
                                                                   std::make_tuple(http::status::ok, 11));
      res->set(http::field::content_type, reply.content_type);
      res->set(http::field::content_disposition, reply.extra_header);
      res->keep_alive(keep_alive);
      res->prepare_payload();
      return write(res);
    }
    auto res = std::make_shared<http::response<http::string_body>>(reply.status, 11);
    res->set(http::field::server, "hilbench");
    res->set(http::field::content_type, reply.content_type);
    if (reply.no_store) res->set(http::field::cache_control, "no-store");
    if (!reply.allow.empty()) res->set(http::field::allow, reply.allow);
    if (!reply.extra_header.empty()) res->set(http::field::content_disposition, reply.extra_header);
    res->keep_alive(keep_alive);
    res->body() = std::move(reply.body);
    if (!reply.length_unknown) res->prepare_payload();
    write(res);
  }

  template <class Response>
  void write(const std::shared_ptr<Response>& res) {
    if constexpr (!std::is_same_v<typename Response::body_type, http::empty_body>) {
      if (head_) {
        // The answer to HEAD is the header alone, its Content-Length that of the body not sent: a
        // body after it would be read by the client as the start of the next answer.
        auto header_only = std::make_shared<http::response<http::empty_body>>();
        header_only->base() = res->base();
        return write(header_only);
      }
    }
    http::async_write(stream_, *res, [self = shared_from_this(), res](beast::error_code ec, std::size_t) {
      if (ec || !res->keep_alive()) return self->close();
      self->read();
    });
  }

  void close() {
    beast::error_code ec;
    stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
    if (draining_) drain();
  }

  // Lingering close: discard what the client still sends (up to 64 MB or 5 s), so that closing
  // with unread data does not reset the connection before the client has read our answer.
  void drain() {
    stream_.expires_after(std::chrono::seconds(5));
    stream_.async_read_some(asio::buffer(scratch_), [self = shared_from_this()](beast::error_code ec, std::size_t n) {
      self->drained_ += n;
      if (!ec && self->drained_ < (64u << 20)) self->drain();
    });
  }

  beast::tcp_stream stream_;
  std::shared_ptr<ApiServer::Impl> api_;
  ConnectionSlot slot_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  bool draining_ = false;
  bool head_ = false;  // the request being answered is a HEAD: its answer has no body
  std::size_t drained_ = 0;
  std::optional<std::chrono::steady_clock::time_point> idle_since_;
  std::array<char, 16384> scratch_{};
};

std::shared_ptr<HttpSession> open_http_session(tcp::socket&& socket, std::shared_ptr<ApiServer::Impl> api) {
  auto session = std::make_shared<HttpSession>(std::move(socket), std::move(api));
  session->read();
  return session;
}

std::optional<std::chrono::steady_clock::time_point> idle_since(const HttpSession& s) { return s.idle_since(); }

void evict(HttpSession& s) { s.evict(); }

}  // namespace hil::bench::api
