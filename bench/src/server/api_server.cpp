#include "api_server.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <map>
#include <mutex>
#include <cmath>
#include <deque>
#include <fstream>
#include <functional>
#include <optional>
#include <random>
#include <sstream>
#include <unordered_map>
#include <variant>

#include <boost/asio/dispatch.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/strand.hpp>
#include <boost/asio/thread_pool.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <spdlog/spdlog.h>

#include "analyses.hpp"
#include "event_feed.hpp"
#include "console/assets.hpp"
#include "foxglove.hpp"
#include "jobs.hpp"
#include "request_guard.hpp"
#include "hil/bench/campaign/run_report.hpp"
#include "hil/config.hpp"
#include "hil/config_files.hpp"
#include "hil/plant/plant.hpp"
#include "hil/units.hpp"
#include "hil/json_file.hpp"
#include "hil/text_file.hpp"

namespace hil::bench {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using nlohmann::json;
using Request = http::request<http::string_body>;

constexpr std::size_t kWsQueueLimit = 1024;  // telemetry messages per client; beyond: dropped and counted
constexpr std::size_t kWsRepliesLimit = 64;  // the session's own messages per client (answers to its requests)

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
std::string dump_json(const json& j, int indent = -1) { return j.dump(indent, ' ', false, json::error_handler_t::replace); }

// An answer held in memory (Reply's other members at their defaults).
Reply body_reply(http::status status, std::string body, std::string content_type) {
  Reply r;
  r.status = status;
  r.body = std::move(body);
  r.content_type = std::move(content_type);
  return r;
}
Reply json_reply(http::status status, const json& j) { return body_reply(status, dump_json(j, 2) + "\n", "application/json"); }
Reply error_reply(http::status status, const std::string& error, const std::string& detail = "", const std::string& field = "") {
  json j = {{"error", error}};
  if (!detail.empty()) j["detail"] = detail;
  if (!field.empty()) j["field"] = field;  // the request field at fault, for a client to point at
  return json_reply(status, j);
}

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

// Thrown inside a handler: becomes an error reply.
struct ApiError {
  http::status status;
  std::string error, detail;
  std::string field = {};  // the body field at fault, where one is
  std::string allow = {};  // a 405's Allow header: the methods the path takes (RFC 9110 15.5.6)
};

// The answer an ApiError stands for, its Allow header included: one conversion for every place
// that catches one.
Reply error_reply(const ApiError& e) {
  Reply r = error_reply(e.status, e.error, e.detail, e.field);
  r.allow = e.allow;
  return r;
}

std::string percent_decode(std::string_view s) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && std::isxdigit(static_cast<unsigned char>(s[i + 1])) &&
        std::isxdigit(static_cast<unsigned char>(s[i + 2]))) {
      out.push_back(static_cast<char>(std::stoi(std::string(s.substr(i + 1, 2)), nullptr, 16)));
      i += 2;
    } else {
      out.push_back(s[i] == '+' ? ' ' : s[i]);
    }
  }
  return out;
}

struct Target {
  std::vector<std::string> path;  // "/api/runs/x" -> {"api", "runs", "x"}
  std::map<std::string, std::string> query;
  std::vector<std::string> repeated;  // query options given more than once (refused: which one was meant?)
};

Target parse_target(std::string_view target) {
  Target t;
  const auto q = target.find('?');
  std::string_view path = target.substr(0, q);
  std::stringstream ps{std::string(path)};
  for (std::string part; std::getline(ps, part, '/');) {
    if (!part.empty()) t.path.push_back(percent_decode(part));
  }
  if (q != std::string_view::npos) {
    std::stringstream qs{std::string(target.substr(q + 1))};
    for (std::string kv; std::getline(qs, kv, '&');) {
      if (kv.empty()) continue;  // "?&a=1", "a=1&&b=2": no option, as in a browser's URLSearchParams
      const auto eq = kv.find('=');
      std::string key = percent_decode(kv.substr(0, eq));
      std::string value = eq == std::string::npos ? "" : percent_decode(kv.substr(eq + 1));
      if (!t.query.emplace(key, std::move(value)).second) t.repeated.push_back(std::move(key));
    }
  }
  return t;
}

// A request target as it may appear in the server log or an error reply: a token in the query is replaced, and
// bytes outside printable ASCII are escaped, so the log neither leaks a secret nor holds raw
// control characters from a client.
std::string loggable_target(beast::string_view raw) {
  const std::string_view target(raw.data(), raw.size());
  std::string out;
  const auto q = target.find('?');
  auto escape = [&out](std::string_view part) {
    for (const char ch : part) {
      const auto c = static_cast<unsigned char>(ch);
      if (c >= 0x20 && c < 0x7f) {
        out.push_back(ch);
      } else {
        static constexpr char kHex[] = "0123456789ABCDEF";
        out += {'%', kHex[c >> 4], kHex[c & 15]};
      }
    }
  };
  escape(target.substr(0, q));
  if (q == std::string_view::npos) return out;
  out.push_back('?');
  for (std::size_t from = q + 1;;) {
    const auto amp = target.find('&', from);
    const std::string_view kv = target.substr(from, amp == std::string_view::npos ? amp : amp - from);
    if (percent_decode(kv.substr(0, kv.find('='))) == "token") {
      out += "token=<redacted>";
    } else {
      escape(kv);
    }
    if (amp == std::string_view::npos) break;
    out.push_back('&');
    from = amp + 1;
  }
  return out;
}

bool constant_time_equal(std::string_view a, std::string_view b) {
  unsigned char diff = a.size() == b.size() ? 0 : 1;
  for (std::size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i % std::max<std::size_t>(b.size(), 1)]);
  return diff == 0;
}

std::vector<std::string> yaml_stems(const std::filesystem::path& dir) {
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    if (e.is_regular_file() && e.path().extension() == ".yaml") out.push_back(e.path().stem().string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

// A request's JSON body: its size is bounded by the parser (--max-body-kb), its nesting here
// before it is parsed, and a key given twice is refused naming it (request_guard.hpp).
json parse_json_body(const Request& req) {
  if (req.body().empty()) return json::object();
  json j;
  try {
    j = parse_request_json(req.body());
  } catch (const JsonRefused& e) {
    throw ApiError{http::status::bad_request, e.field.empty() ? "malformed JSON" : "duplicate key", e.what(), e.field};
  }
  if (!j.is_object()) throw ApiError{http::status::bad_request, "malformed JSON", "the body must be a JSON object"};
  return j;
}

template <class T>
T field(const json& j, const char* key, T fallback) {
  if (!j.contains(key) || j[key].is_null()) return fallback;
  try {
    return j[key].get<T>();
  } catch (const json::exception&) {
    throw ApiError{http::status::bad_request, "bad field", std::string("'") + key + "' has the wrong type", key};
  }
}

double number_field(const json& j, const char* key) {
  if (!j.contains(key) || !j[key].is_number()) {
    throw ApiError{http::status::bad_request, "bad field", std::string("'") + key + "' must be a number", key};
  }
  const double v = j[key].get<double>();
  if (!std::isfinite(v)) throw ApiError{http::status::bad_request, "bad field", std::string("'") + key + "' must be finite", key};
  return v;
}

// `name` (a body field or a query option) when it is not one of `allowed`: 400 `error`, with a
// "did you mean" and `after` in the detail. `shown` is the name as it may be echoed.
void refuse_unknown(const std::string& name, const std::string& shown, const std::vector<std::string>& allowed, const char* error,
                    const std::string& after = "") {
  if (std::find(allowed.begin(), allowed.end(), name) != allowed.end()) return;
  const std::string hint = cfg::closest(name, allowed);
  throw ApiError{http::status::bad_request, error,
                 "'" + shown + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)") + after, shown};
}

void allow_fields(const json& j, std::initializer_list<const char*> allowed) {
  const std::vector<std::string> names(allowed.begin(), allowed.end());
  for (const auto& item : j.items()) refuse_unknown(item.key(), item.key(), names, "unknown field");
}

// A number given in the query (`key`): the whole text is the number (cfg::parse_number), so
// "20abc" is refused rather than read as 20.
double query_number(const Target& t, const char* key, double fallback) {
  const auto q = t.query.find(key);
  if (q == t.query.end()) return fallback;
  double value = 0;
  if (!cfg::parse_number(q->second, value)) {
    throw ApiError{http::status::bad_request, "bad field",
                   std::string("'") + key + "' must be a number, got '" + printable(q->second, 40) + "'", key};
  }
  return value;
}

// The rows per second a telemetry WebSocket asks for (?rate_hz=N, 20 when not given), once its
// options are checked against its route's (refuse_unknown_query). A half-number (?rate_hz=20abc)
// is refused: silently streaming at another rate than asked for hides the mistake.
double telemetry_rate_hz(const Target& t) {
  const double rate_hz = query_number(t, "rate_hz", 20);
  if (!(rate_hz > 0 && rate_hz <= 5000))
    throw ApiError{http::status::bad_request, "bad field", "'rate_hz' must be in (0, 5000] rows per second", "rate_hz"};
  return rate_hz;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// WebSocket session: accepts the upgrade, then writes telemetry. A plain session reads only to
// notice the close; a Foxglove session also takes the client's subscribe/unsubscribe.

// Whether the client offered the Foxglove subprotocol (Sec-WebSocket-Protocol is a list).
bool offers_foxglove(const Request& req) {
  const auto offered = req[http::field::sec_websocket_protocol];
  std::string_view list(offered.data(), offered.size());
  while (!list.empty()) {
    const auto comma = list.find(',');
    std::string_view item = list.substr(0, comma);
    while (!item.empty() && item.front() == ' ') item.remove_prefix(1);
    while (!item.empty() && item.back() == ' ') item.remove_suffix(1);
    if (item == foxglove::kSubprotocol) return true;
    if (comma == std::string_view::npos) break;
    list.remove_prefix(comma + 1);
  }
  return false;
}

// Beast refuses a handshake it cannot complete (no Sec-WebSocket-Key, a version other than 13, no
// Host) with its message as plain text; the API's errors are JSON, so the refusal becomes the same
// error body, naming the header at fault. The decorator sees only the response, and Beast's
// message names the header ("The WebSocket handshake Sec-WebSocket-Key field is missing").
void refused_handshake(websocket::response_type& res) {
  const std::string why = res.body();
  std::string header;
  for (const char* name : {"Sec-WebSocket-Key", "Sec-WebSocket-Version", "Host"}) {
    if (why.find(std::string(" ") + name + " field") != std::string::npos) header = name;
  }
  const Reply reply = error_reply(res.result(), "WebSocket handshake refused", why, header);
  res.set(http::field::content_type, reply.content_type);
  res.body() = reply.body;
  res.prepare_payload();
}

// One open client connection, HTTP or WebSocket, counted while it lives: the server takes at
// most kMaxConnections at once. A flood of idle sockets (20 000 from one client) took every file
// descriptor the process had, and the next run could not write its run.json.
// Telemetry streams take at most kMaxStreams of them: 256 streams took every connection, and an
// abort was closed at accept for as long as they stayed. The other kMaxConnections - kMaxStreams
// are the operator's requests' (HTTP), where the longest idle one gives way to a newcomer, so a
// control request always finds a place. A stream past its share is refused 503.
constexpr int kMaxConnections = 320;
constexpr int kMaxStreams = 256;
class ConnectionSlot {
 public:
  explicit ConnectionSlot(std::shared_ptr<std::atomic<int>> open) : open_(std::move(open)) { ++*open_; }
  ConnectionSlot(ConnectionSlot&& other) noexcept = default;  // the moved-from slot holds nothing
  ConnectionSlot(const ConnectionSlot&) = delete;
  ConnectionSlot& operator=(const ConnectionSlot&) = delete;
  ConnectionSlot& operator=(ConnectionSlot&&) = delete;
  ~ConnectionSlot() {
    if (open_) --*open_;
  }

 private:
  std::shared_ptr<std::atomic<int>> open_;
};

namespace {

// The connection of a WebSocket session: what the HTTP session had read past the upgrade request
// is read first, then the socket. A client may send its first frames in the same write as the
// upgrade (a Foxglove subscribe, a ping); handed over as a bare socket, those bytes were lost and
// the client waited for an answer that never came.
class UpgradedStream : public beast::buffered_read_stream<beast::tcp_stream, beast::flat_buffer> {
 public:
  using buffered_read_stream::buffered_read_stream;
};

// The WebSocket close on it is the TCP stream's (Beast looks these up by argument).
[[maybe_unused]] void teardown(beast::role_type role, UpgradedStream& stream, beast::error_code& ec) {
  using beast::websocket::teardown;
  teardown(role, stream.next_layer(), ec);
}
template <class Handler>
void async_teardown(beast::role_type role, UpgradedStream& stream, Handler&& handler) {
  using beast::websocket::async_teardown;
  async_teardown(role, stream.next_layer(), std::forward<Handler>(handler));
}

}  // namespace

class WsSession : public std::enable_shared_from_this<WsSession> {
 public:
  // read_ahead: the bytes the HTTP session read past the upgrade request, the client's first frames.
  // session_id: Foxglove's serverInfo.sessionId, the server's (ApiServer::Impl::session_id).
  // idle_timeout: ApiOptions::ws_idle_timeout. stream_slot: its place in the telemetry share.
  WsSession(tcp::socket&& socket, beast::flat_buffer read_ahead, TelemetryHub& hub, bool foxglove, std::string session_id,
            ConnectionSlot slot, ConnectionSlot stream_slot, std::chrono::milliseconds idle_timeout)
      : ws_(std::move(socket)),
        hub_(hub),
        foxglove_(foxglove),
        session_id_(std::move(session_id)),
        slot_(std::move(slot)),
        stream_slot_(std::move(stream_slot)),
        idle_timeout_(idle_timeout) {
    ws_.next_layer().buffer() = std::move(read_ahead);
  }
  WsSession(const WsSession&) = delete;
  WsSession& operator=(const WsSession&) = delete;
  ~WsSession() {
    hub_.unsubscribe(this);
    if (dropped_ > 0) spdlog::info("telemetry WebSocket closed; {} messages were dropped for a slow reader", dropped_);
    if (replies_dropped_ > 0)
      spdlog::info("telemetry WebSocket closed; {} answers to its requests were dropped (it asked without reading)",
                   replies_dropped_);
  }

  void run(Request req, double rate_hz) {
    // Idle means nothing received, not nothing sent: a client that only reads sends nothing of its
    // own, and was cut at exactly 300 s (Foxglove, ctl telemetry five minutes into a soak). The
    // server pings at half the idle time; every WebSocket client answers a ping as it reads, so a
    // reading client is never idle, and one that is gone (no pong) is closed at the idle time.
    websocket::stream_base::timeout timeouts = websocket::stream_base::timeout::suggested(beast::role_type::server);
    timeouts.idle_timeout = idle_timeout_;
    timeouts.keep_alive_pings = true;
    ws_.set_option(timeouts);
    ws_.set_option(websocket::stream_base::decorator([foxglove = foxglove_](websocket::response_type& res) {
      res.set(http::field::server, "hilbench");
      if (res.result() != http::status::switching_protocols) return refused_handshake(res);
      if (foxglove) res.set(http::field::sec_websocket_protocol, std::string(foxglove::kSubprotocol));
    }));
    ws_.read_message_max(kWsClientMessageMax);
    ws_.async_accept(req, [self = shared_from_this(), rate_hz](beast::error_code ec) {
      if (ec) return;
      if (self->foxglove_) {
        self->send_text(dump_json(foxglove::server_info(self->session_id_)));
        self->send_text(dump_json(foxglove::advertise()));
      } else {
        json names = json::array();
        for (const auto& c : telemetry_columns(ColumnSet::all)) names.push_back(c.name);
        self->send_text(dump_json({{"type", "hello"}, {"rate_hz", rate_hz}, {"columns", names}}));
      }
      self->hub_.subscribe(self, rate_hz, self->foxglove_);
      self->read();
    });
  }

  // A message of the telemetry stream: a JSON text, or a Foxglove frame (one Message Data frame
  // per subscription whose channel has a payload in it).
  using Message = std::variant<std::shared_ptr<const std::string>, std::shared_ptr<const foxglove::Frame>>;
  // Any thread: the messages of one round of the hub, in order, in one handler of the session.
  void send(std::vector<Message> batch) {
    asio::post(ws_.get_executor(), [self = shared_from_this(), batch = std::move(batch)] {
      for (const auto& m : batch) {
        if (const auto* text = std::get_if<std::shared_ptr<const std::string>>(&m)) {
          self->enqueue({*text, false, true});
          continue;
        }
        const auto& frame = std::get<std::shared_ptr<const foxglove::Frame>>(m);
        for (const auto& [subscription, channel] : self->subscriptions_) {
          const std::string& payload = frame->payloads[channel];
          if (!payload.empty())
            self->enqueue(
                {std::make_shared<const std::string>(foxglove::message_data(subscription, frame->timestamp_ns, payload)), true,
                 true});
        }
      }
    });
  }

 private:
  struct Outgoing {
    std::shared_ptr<const std::string> bytes;
    bool binary;
    bool telemetry;  // of the hub's stream (rows, notices), not the session's own message
  };
  static constexpr std::size_t kWsClientMessageMax = 64 * 1024;

  // The session's own message: the hello, Foxglove's serverInfo and advertise, an answer to the client.
  void send_text(std::string text) { enqueue({std::make_shared<const std::string>(std::move(text)), false, false}); }

  // Session thread. What is dropped, and told to the client as dropped, is telemetry only: the
  // session's answers to a client's requests counted as dropped rows before, so a client sending
  // bad requests was told it had missed telemetry it had not. Those answers have their own bound
  // (a client that asks without reading loses answers, not the server's memory).
  void enqueue(Outgoing message) {
    if (closed_) return;
    if (message.telemetry && telemetry_queued_ >= kWsQueueLimit) {
      ++dropped_;
      ++dropped_unreported_;
      return;
    }
    if (!message.telemetry && queue_.size() - telemetry_queued_ >= kWsRepliesLimit) {
      ++replies_dropped_;
      return;
    }
    push(std::move(message));
    if (queue_.size() == 1) write();
  }

  void push(Outgoing message) {
    if (message.telemetry) ++telemetry_queued_;
    queue_.push_back(std::move(message));
  }

  void write() {
    ws_.binary(queue_.front().binary);
    ws_.async_write(asio::buffer(*queue_.front().bytes), [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) {
        self->closed_ = true;
        self->queue_.clear();
        self->telemetry_queued_ = 0;
        self->hub_.unsubscribe(self.get());
        return;
      }
      if (self->queue_.front().telemetry) --self->telemetry_queued_;
      self->queue_.pop_front();
      // The client learns in-band what it missed, once there is room to tell it.
      if (self->dropped_unreported_ > 0 && self->telemetry_queued_ < kWsQueueLimit / 2) {
        const std::string why = "this client read slower than the telemetry was sent; telemetry.csv is the lossless record";
        const json notice =
            self->foxglove_
                ? foxglove::status(1, std::to_string(self->dropped_unreported_) + " messages dropped (" +
                                          std::to_string(self->dropped_) + " in all): " + why)
                : json{{"type", "dropped"}, {"messages", self->dropped_unreported_}, {"total", self->dropped_}, {"why", why}};
        self->push({std::make_shared<const std::string>(dump_json(notice)), false, false});
        self->dropped_unreported_ = 0;
      }
      if (!self->queue_.empty()) self->write();
    });
  }

  void read() {
    ws_.async_read(buffer_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) {
        self->closed_ = true;
        self->hub_.unsubscribe(self.get());
        return;
      }
      if (self->foxglove_) self->on_client_message();  // plain clients have nothing to say
      self->buffer_.consume(self->buffer_.size());
      self->read();
    });
  }

  // A Foxglove client's request; what is not understood is answered with a status message.
  void on_client_message() {
    if (!ws_.got_text())
      return send_text(dump_json(foxglove::status(2, "binary messages (client publishing) are not supported")));
    const std::string_view text(static_cast<const char*>(buffer_.data().data()), buffer_.size());
    const auto op = foxglove::parse_client_op(text);
    if (const auto* e = std::get_if<foxglove::Error>(&op)) return send_text(dump_json(foxglove::status(2, e->message)));
    if (const auto* u = std::get_if<foxglove::Unsubscribe>(&op)) {
      for (const std::uint32_t id : u->subscription_ids) subscriptions_.erase(id);
      return;
    }
    for (const auto& [id, channel_id] : std::get<foxglove::Subscribe>(op).subscriptions) {
      std::size_t index = 0;
      while (index < foxglove::channels().size() && foxglove::channels()[index].id != channel_id) ++index;
      if (index == foxglove::channels().size()) {
        send_text(dump_json(foxglove::status(2, "subscribe: channel " + std::to_string(channel_id) + " is not advertised")));
      } else if (subscriptions_.count(id) != 0) {
        send_text(dump_json(foxglove::status(2, "subscribe: subscription id " + std::to_string(id) + " is in use")));
      } else if (std::any_of(subscriptions_.begin(), subscriptions_.end(), [&](const auto& s) { return s.second == index; })) {
        send_text(dump_json(foxglove::status(2, "subscribe: channel " + std::to_string(channel_id) + " is already subscribed")));
      } else {
        subscriptions_.emplace(id, index);
      }
    }
  }

  websocket::stream<UpgradedStream> ws_;
  TelemetryHub& hub_;
  const bool foxglove_;
  const std::string session_id_;
  ConnectionSlot slot_;         // handed over from the HTTP session it was upgraded from
  ConnectionSlot stream_slot_;  // its place in the telemetry streams' share (kMaxStreams)
  const std::chrono::milliseconds idle_timeout_;
  std::map<std::uint32_t, std::size_t> subscriptions_;  // Foxglove: subscription id -> index in foxglove::channels()
  beast::flat_buffer buffer_;
  std::deque<Outgoing> queue_;
  std::size_t telemetry_queued_ = 0;  // of queue_
  std::size_t dropped_ = 0, dropped_unreported_ = 0, replies_dropped_ = 0;
  bool closed_ = false;
};

// ---------------------------------------------------------------------------------------------
// Telemetry hub.

void TelemetryHub::subscribe(const std::shared_ptr<WsSession>& s, double rate_hz, bool foxglove) {
  std::lock_guard lock(mutex_);
  subs_.push_back({s, s.get(), 1.0 / rate_hz, -1e300, foxglove});
}

void TelemetryHub::unsubscribe(const WsSession* s) {
  std::lock_guard lock(mutex_);
  std::erase_if(subs_, [s](const Sub& x) { return x.key == s; });
}

std::size_t TelemetryHub::subscribers() const {
  std::lock_guard lock(mutex_);
  return subs_.size();
}

TelemetryHub::TelemetryHub() : thread_([this] { fan_out_loop(); }) {}

TelemetryHub::~TelemetryHub() { stop(); }

void TelemetryHub::stop() {
  {
    std::lock_guard lock(inbox_mutex_);
    stop_ = true;
  }
  inbox_cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void TelemetryHub::publish_row(const TelemetryRecord& r) { enqueue({r, nullptr}); }

void TelemetryHub::publish_notice(const json& j) { enqueue({TelemetryRecord{}, std::make_shared<const json>(j)}); }

void TelemetryHub::publish_status(const json& j) { enqueue({TelemetryRecord{}, std::make_shared<const json>(j), true}); }

void TelemetryHub::enqueue(Item item) {
  bool wake = false;
  {
    std::lock_guard lock(inbox_mutex_);
    if (stop_) return;
    if (inbox_.size() >= kInboxItems && !item.status) {
      ++inbox_dropped_;
      return;
    }
    wake = inbox_.empty();
    inbox_.push_back(std::move(item));
  }
  if (wake) inbox_cv_.notify_one();
}

void TelemetryHub::fan_out_loop() {
  // Below the recorder and the API (nice 10): watchers get what is left of the machine.
  ::setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), 10);
  std::vector<Item> items;
  std::uint64_t dropped_said = 0, dropped_now = 0;
  for (;;) {
    {
      std::unique_lock lock(inbox_mutex_);
      inbox_cv_.wait(lock, [this] { return stop_ || !inbox_.empty(); });
      if (stop_) return;
      // A round gathers 10 ms of rows: each session gets at most 100 handlers a second on the io
      // thread, whatever the loop's rate (a handler per row drowned the API's answers).
      inbox_cv_.wait_for(lock, std::chrono::milliseconds(10), [this] { return stop_; });
      if (stop_) return;
      items.swap(inbox_);
      dropped_now = inbox_dropped_;
    }
    if (dropped_now > dropped_said) {  // said outside the lock: the recorder never waits on the log
      spdlog::warn("telemetry stream: {} rows and notices not streamed (the fan-out fell behind); telemetry.csv has them",
                   dropped_now - dropped_said);
      dropped_said = dropped_now;
    }
    fan_out(items);
    items.clear();
  }
}

void TelemetryHub::fan_out(const std::vector<Item>& items) {
  // Each session's messages of this round, in order. Decided under the lock, sent outside it: a
  // session's last reference may die in here, and its destructor unsubscribes.
  std::vector<std::pair<std::shared_ptr<WsSession>, std::vector<WsSession::Message>>> out;
  std::unordered_map<const WsSession*, std::size_t> index;
  auto batch_of = [&](std::shared_ptr<WsSession> session) -> std::vector<WsSession::Message>& {
    const auto [it, added] = index.emplace(session.get(), out.size());
    if (added) out.emplace_back(std::move(session), std::vector<WsSession::Message>{});
    return out[it->second].second;
  };
  struct Due {
    std::shared_ptr<WsSession> session;
    bool foxglove;
    double comp_rad;  // the largest jump since this client's last row: a one-period jump is not decimated away
  };
  std::vector<Due> due;
  for (const Item& item : items) {
    due.clear();
    double t_s = 0;
    {
      std::lock_guard lock(mutex_);
      if (item.notice) {
        t_s = last_t_s_;
        for (auto& s : subs_) {
          if (item.status) {
            if (s.foxglove) continue;
            if (auto session = s.session.lock()) due.push_back({std::move(session), false, 0});
            continue;
          }
          s.next_t_s = -1e300;
          if (auto session = s.session.lock()) due.push_back({std::move(session), s.foxglove, 0});
        }
      } else {
        const double t = item.row.step.t_s;
        last_t_s_ = t;
        for (auto& s : subs_) {
          if (t < s.next_t_s - 2 * s.interval_s) s.next_t_s = t;  // time went back: a new run
          if (std::abs(item.row.step.comp_rad) > std::abs(s.held_comp_rad)) s.held_comp_rad = item.row.step.comp_rad;
          if (t + 1e-9 < s.next_t_s) continue;
          s.next_t_s = s.next_t_s + s.interval_s > t ? s.next_t_s + s.interval_s : t + s.interval_s;
          if (auto session = s.session.lock()) due.push_back({std::move(session), s.foxglove, s.held_comp_rad});
          s.held_comp_rad = 0;
        }
      }
    }
    if (due.empty()) continue;
    if (item.notice) {
      const json& j = *item.notice;
      if (j.contains("t_s") && j["t_s"].is_number()) t_s = j["t_s"].get<double>();
      const auto message = std::make_shared<const std::string>(dump_json(j));
      std::shared_ptr<const foxglove::Frame> frame;
      for (auto& d : due) {
        if (d.foxglove && !frame)
          frame = std::make_shared<const foxglove::Frame>(foxglove::events_frame(foxglove::timestamp_ns(t_s), *message));
        batch_of(std::move(d.session)).push_back(d.foxglove ? WsSession::Message(frame) : WsSession::Message(message));
      }
      continue;
    }
    // One message of each kind per distinct row (the record itself, or it with a held jump).
    std::vector<std::pair<double, std::shared_ptr<const std::string>>> rows;
    std::vector<std::pair<double, std::shared_ptr<const foxglove::Frame>>> frames;
    auto with_comp = [&item](double comp_rad) {
      TelemetryRecord copy = item.row;
      copy.step.comp_rad = comp_rad;
      return copy;
    };
    for (auto& d : due) {
      if (d.foxglove) {
        auto it = std::find_if(frames.begin(), frames.end(), [&](const auto& f) { return f.first == d.comp_rad; });
        if (it == frames.end()) {
          const TelemetryRecord rec = with_comp(d.comp_rad);
          frames.emplace_back(d.comp_rad, std::make_shared<const foxglove::Frame>(
                                              foxglove::Frame{foxglove::timestamp_ns(rec.step.t_s), foxglove::payloads(rec)}));
          it = frames.end() - 1;
        }
        batch_of(std::move(d.session)).push_back(it->second);
      } else {
        auto it = std::find_if(rows.begin(), rows.end(), [&](const auto& f) { return f.first == d.comp_rad; });
        if (it == rows.end()) {
          json j = {{"type", "row"}};
          const auto values = telemetry_row(with_comp(d.comp_rad));
          const auto& columns = telemetry_columns(ColumnSet::all);
          for (std::size_t i = 0; i < columns.size(); ++i)
            j[columns[i].name] = std::isfinite(values[i]) ? json(values[i]) : json(nullptr);
          rows.emplace_back(d.comp_rad, std::make_shared<const std::string>(dump_json(j)));
          it = rows.end() - 1;
        }
        batch_of(std::move(d.session)).push_back(it->second);
      }
    }
  }
  for (auto& [session, batch] : out) session->send(std::move(batch));
}

// ---------------------------------------------------------------------------------------------
// The routes.

class HttpSession;

namespace {

// This server process's Foxglove sessionId: the same for every connection to it and new at each
// start, so that a client reconnecting can tell a restarted server from a dropped connection. The
// start time and random bits, never an address (a heap pointer told any client the process's
// memory layout, which address-space randomisation is there to hide).
std::string new_session_id() {
  std::random_device random;
  const auto start_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  char text[64];
  std::snprintf(text, sizeof text, "%llx-%08x%08x", static_cast<unsigned long long>(start_ns), random(), random());
  return text;
}

}  // namespace

namespace {

// Whether runs_dir/id is a run folder: a plain name, a folder itself (not a link to one
// elsewhere), holding a run.json (of any kind: reading it says what is wrong with it).
bool is_run_dir(const std::filesystem::path& runs_dir, const std::string& id) {
  if (!cfg::plain_name(id)) return false;
  std::error_code ec;
  return std::filesystem::symlink_status(runs_dir / id, ec).type() == std::filesystem::file_type::directory &&
         std::filesystem::symlink_status(runs_dir / id / "run.json", ec).type() != std::filesystem::file_type::not_found;
}

// Whether a folder entry is a regular file itself, not a link to one.
bool plain_file(const std::filesystem::directory_entry& e) {
  std::error_code ec;
  return e.symlink_status(ec).type() == std::filesystem::file_type::regular;
}

// A file below `base` (parts: plain names), opened now without following a symbolic link at any
// part (open_inside): what is served is the file that was checked, never one a link points at
// outside the runs folder (a tester's events.jsonl -> /etc/passwd was served). 404 `missing`
// when it is not there, 403 naming the path (never its content) when it is a link or no file.
Reply opened_file(const std::filesystem::path& base, const std::vector<std::string>& parts, const std::string& missing) {
  std::filesystem::path path = base;
  for (const auto& p : parts) path /= p;
  bool absent = false;
  OpenedFile f;
  try {
    f = open_inside(base, parts, &absent);
  } catch (const std::exception& e) {
    throw ApiError{http::status::forbidden, "file not served", e.what()};
  }
  if (absent) throw ApiError{http::status::not_found, "unknown file", missing};
  Reply r;
  r.file = path;
  r.fd = std::shared_ptr<const int>(new int(f.fd), [](const int* fd) {
    if (*fd >= 0) ::close(*fd);
    delete fd;
  });
  return r;
}

Reply html_file(const std::filesystem::path& base, const std::vector<std::string>& parts) {
  Reply r = parts.empty() ? Reply{} : opened_file(base, parts, "no file " + parts.back());
  r.content_type = "text/html; charset=utf-8";
  r.extra_header = "inline";
  return r;
}

}  // namespace

struct ApiServer::Impl : std::enable_shared_from_this<ApiServer::Impl> {
  Impl(asio::io_context& io_, ApiOptions o, CampaignRunner& r, TelemetryHub& h)
      : io(io_), options(std::move(o)), runner(r), hub(h), acceptor(io_), jobs(options.max_waiting_jobs) {}

  asio::io_context& io;
  ApiOptions options;
  CampaignRunner& runner;
  TelemetryHub& hub;
  tcp::acceptor acceptor;
  // Why new campaigns and jobs are refused (shutting down), or empty; read on the io thread and on
  // the run files' thread (start_analysis).
  std::string refusing() const {
    std::lock_guard lock(refuse_mutex);
    return refuse_starts;
  }
  mutable std::mutex refuse_mutex;
  std::string refuse_starts;  // under refuse_mutex
  // The thread that answers every request under /api/runs: they read run folders (run.json,
  // analyses, reports' state), which never happens on the io thread that answers status, abort and
  // the telemetry streams (a run.json nested 20 000 deep held them all for 7 s). One thread: the
  // checks and submits of jobs (run_report, start_analysis) keep one order. Joined by ~ApiServer.
  asio::thread_pool files{1};
  std::shared_ptr<std::atomic<int>> open_connections = std::make_shared<std::atomic<int>>(0);
  std::shared_ptr<std::atomic<int>> open_streams = std::make_shared<std::atomic<int>>(0);  // telemetry WebSockets
  std::chrono::steady_clock::time_point last_stream_refusal_logged{};                      // io thread only
  std::chrono::steady_clock::time_point last_refusal_logged{};                             // io thread only
  // The HTTP sessions, for evicting the longest-idle one when the connections are at their cap
  // (io thread only; expired ones are pruned there).
  std::vector<std::weak_ptr<HttpSession>> http_sessions;
  JobQueue jobs;                                    // submitted to on the io thread only: a check and its submit never race
  const std::string session_id = new_session_id();  // Foxglove's serverInfo.sessionId
  // The entry of each config file in GET /api/campaigns, /api/rigs and /api/models, with the files
  // its load read (a rig's device files and register maps, a campaign's plant and CSV reference):
  // parsed again only when one of them has changed. Io thread only.
  struct Listing {
    json entry;
    std::vector<cfg::FileStamp> files;
  };
  using Listings = std::map<std::string, Listing>;  // by the file's stem
  Listings campaign_listings, rig_listings, model_listings;
  // The entries of dir/*.yaml, each {"name", "file"} and what `describe` adds (or its "error"),
  // from `kept` while every file read for it is unchanged. `kept` becomes this listing: files
  // gone are forgotten.
  json listing(Listings& kept, const std::filesystem::path& dir,
               const std::function<void(const std::filesystem::path& file, json& entry)>& describe);

  void accept();
  bool evict_longest_idle();
  bool authorised(const Request& req, const Target& t) const;
  // Host and Origin against the names this server answers (request_guard.hpp): the refusal, or nothing.
  std::optional<Reply> refused_header(const Request& req) const;
  std::optional<HostGuard> guard;  // set once the port is bound
  // A parsed request's answer: authorisation, the route, errors as replies, the log line.
  Reply answer(const Request& req, const Target& t);
  // The answer to a request the HTTP parser refused.
  Reply parse_failure(const beast::error_code& ec) const;
  Reply handle(const Request& req, const Target& t);
  Reply campaigns();
  Reply rigs();
  Reply start(const Request& req, const Target& t);
  Reply stop();
  Reply abort(const Request& req);
  Reply inject(const std::string& what, const json& body);
  Reply runs();
  Reply run(const std::string& id);
  Reply run_file(const std::string& id, const std::string& file);
  Reply run_events(const std::string& id, const Target& t);
  // head: a HEAD request, answered without making the report.
  Reply run_report(const std::string& id, const Target& t, bool head);
  Reply models();
  Reply analyses(const std::string& id);
  Reply start_analysis(const std::string& id, const Request& req);
  Reply analysis(const std::string& id, const std::string& aid);
  Reply analysis_file(const std::string& id, const std::string& aid, const std::string& file);
  RigConfig rig_named(const std::string& name) const;
  // The folder of a recorded run (404 otherwise) and its record (422 when unreadable), 409 while it runs.
  std::filesystem::path ended_run(const std::string& id, RunRecord* record = nullptr) const;
  // A run folder's record as the API shows it: its run.json, or, while that file still says
  // "running" for a run this server ended, the end the runner keeps (CampaignRunner::unrecorded_end).
  RunRecord record_of(const std::filesystem::path& dir) const {
    RunRecord r = read_run_record_inside(dir);
    if (r.outcome == Outcome::running) {
      if (auto end = runner.unrecorded_end(dir.filename().string())) return std::move(end->record);
    }
    return r;
  }
  // An analysis of the run, from the jobs (queued, running, failed) or from its folder (done).
  std::optional<json> find_analysis(const std::string& id, const std::string& aid) const;
};

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

RigConfig ApiServer::Impl::rig_named(const std::string& name) const {
  const auto names = yaml_stems(options.rigs_dir);
  if (!cfg::plain_name(name) || std::find(names.begin(), names.end(), name) == names.end()) {
    const std::string hint = cfg::closest(name, names);
    throw ApiError{
        http::status::not_found, "unknown rig",
        "'" + name + "' is not a rig in " + options.rigs_dir.string() + (hint.empty() ? "" : " (did you mean '" + hint + "'?)")};
  }
  if (!resolves_inside(options.rigs_dir / (name + ".yaml"), options.rigs_dir)) {
    throw ApiError{http::status::conflict, "rig file not read",
                   (options.rigs_dir / (name + ".yaml")).string() + " is a symbolic link to a file outside " +
                       options.rigs_dir.string() + ": not read",
                   "rig"};
  }
  try {
    return load_rig_config(options.rigs_dir / (name + ".yaml"));
  } catch (const cfg::Error& e) {
    // The request is sound, the rig it names is not usable as its files stand: a conflict with the
    // bench's state that the operator fixes in the file (GET /api/rigs lists the same error), not
    // a server failure.
    throw ApiError{http::status::conflict, "invalid rig file", e.what(), "rig"};
  }
}

// Loading a config file runs on the io thread, which serves every request: an unchanged one is not
// loaded again (a large register map took seconds at each GET /api/rigs; every campaign, its plant
// and its reference CSV were parsed at each GET /api/campaigns, every plant model at each GET
// /api/models).
json ApiServer::Impl::listing(Listings& kept, const std::filesystem::path& dir,
                              const std::function<void(const std::filesystem::path& file, json& entry)>& describe) {
  Listings now;
  json list = json::array();
  for (const auto& name : yaml_stems(dir)) {
    if (const auto old = kept.find(name); old != kept.end() && cfg::unchanged(old->second.files)) {
      list.push_back(old->second.entry);
      now.insert(kept.extract(old));
      continue;
    }
    const auto file = dir / (name + ".yaml");
    json j = {{"name", name}, {"file", file.string()}};
    cfg::ReadFiles read;
    try {
      // A file that is a link to one outside its folder (a model -> /etc/shadow) is not read: a
      // YAML error would quote its first line to any client.
      if (!resolves_inside(file, dir))
        throw std::runtime_error(file.string() + ": a symbolic link to a file outside " + dir.string() + ": not read");
      describe(file, j);
    } catch (const std::exception& e) {
      j["error"] = e.what();
    }
    list.push_back(j);
    now.emplace(name, Listing{std::move(j), read.files()});
  }
  kept = std::move(now);
  return list;
}

Reply ApiServer::Impl::campaigns() {
  const json list = listing(campaign_listings, options.campaigns_dir, [](const std::filesystem::path& file, json& j) {
    const Campaign c = load_campaign(file);
    j["description"] = c.description;
    j["duration_s"] = c.duration_s;
    j["period_ms"] = c.period_s * 1e3;
    j["runs"] = json::array();
    for (const auto& r : c.runs) j["runs"].push_back(r.name);
  });
  return json_reply(http::status::ok, {{"campaigns", list}});
}

Reply ApiServer::Impl::rigs() {
  const json list = listing(rig_listings, options.rigs_dir, [](const std::filesystem::path& file, json& j) {
    const RigConfig r = load_rig_config(file);
    j["kind"] = r.kind;
    j["description"] = r.description;
    j["priority"] = r.loop.priority;
    j["cpu"] = r.loop.cpu;
    j["following_error"] =
        r.safety.watches_following()
            ? json{{"max_deg", std::round(units::rad_to_deg(r.safety.following_error_rad) * 1e9) / 1e9},  // as written
                   {"time_ms", std::lround(r.safety.following_error_s * 1000)}}
            : json(nullptr);
    if (const std::string w = rig_warning(r); !w.empty()) j["warning"] = w;
  });
  return json_reply(http::status::ok, {{"rigs", list}});
}

Reply ApiServer::Impl::start(const Request& req, const Target& t) {
  if (const std::string why = refusing(); !why.empty())
    throw ApiError{http::status::service_unavailable, "not accepting campaigns", why};
  const std::string content_type(req[http::field::content_type]);
  const bool yaml_body = content_type.find("yaml") != std::string::npos;
  json body = yaml_body ? json::object() : parse_json_body(req);
  if (!yaml_body) {
    allow_fields(body, {"campaign", "campaign_yaml", "rig", "runs", "speed"});
    // The query's options (the route's) are a YAML body's: beside a JSON body they were ignored,
    // and ?rig=hybrid started on sim.
    for (const auto& item : t.query) {
      if (item.first == "token") continue;
      const std::string shown = loggable_target(item.first);
      throw ApiError{http::status::bad_request, "unknown query option",
                     "'" + shown + "': a JSON body carries its options in the body; the query carries them for a YAML body",
                     shown};
    }
  }
  // Options come from the JSON body, or from the query when the body is the YAML itself.
  auto option = [&](const char* key) -> std::optional<std::string> {
    if (yaml_body) {
      const auto q = t.query.find(key);
      return q == t.query.end() ? std::nullopt : std::optional<std::string>(q->second);
    }
    return std::nullopt;
  };

  StartRequest s;
  const std::string rig = yaml_body ? option("rig").value_or("sim") : field<std::string>(body, "rig", "sim");
  s.rig = rig_named(rig);
  const std::string warning = rig_warning(s.rig);
  if (yaml_body) {
    if (const auto runs = option("runs")) s.runs = cfg::comma_list(*runs);
    if (option("speed")) s.speed = query_number(t, "speed", s.speed);
  } else {
    s.runs = field<std::vector<std::string>>(body, "runs", {});
    if (body.contains("speed")) s.speed = number_field(body, "speed");
  }
  // No subset means every run. A subset given empty ([], ?runs=, a name lost to a bug in a script)
  // ran them all, the opposite of a choice; a name given twice is a mistake too.
  const bool runs_given = yaml_body ? option("runs").has_value() : body.contains("runs") && !body["runs"].is_null();
  if (runs_given && s.runs.empty()) {
    throw ApiError{http::status::bad_request, "bad field",
                   "'runs' names no run: name at least one, or leave 'runs' out to run them all", "runs"};
  }
  if (const std::string* twice = cfg::repeated(s.runs))
    throw ApiError{http::status::bad_request, "bad field", "'runs' names '" + *twice + "' twice", "runs"};

  std::string yaml;
  if (yaml_body) {
    yaml = req.body();
  } else if (body.contains("campaign_yaml")) {
    yaml = field<std::string>(body, "campaign_yaml", "");
  }
  try {
    if (yaml_body || body.contains("campaign_yaml")) {
      if (body.contains("campaign"))
        throw ApiError{http::status::bad_request, "bad request", "give 'campaign' or 'campaign_yaml', not both"};
      s.campaign = load_campaign_text(yaml, "posted campaign", options.campaigns_dir, options.campaigns_dir.parent_path());
      s.source = "posted";
    } else {
      if (!body.contains("campaign")) {
        throw ApiError{http::status::bad_request, "bad request",
                       "give 'campaign' (a name from GET /api/campaigns) or 'campaign_yaml'"};
      }
      const std::string name = field<std::string>(body, "campaign", "");
      const auto names = yaml_stems(options.campaigns_dir);
      if (!cfg::plain_name(name) || std::find(names.begin(), names.end(), name) == names.end()) {
        const std::string hint = cfg::closest(name, names);
        throw ApiError{http::status::not_found, "unknown campaign",
                       "'" + name + "' is not a campaign in " + options.campaigns_dir.string() +
                           (hint.empty() ? "" : " (did you mean '" + hint + "'?)")};
      }
      const auto file = options.campaigns_dir / (name + ".yaml");
      if (!resolves_inside(file, options.campaigns_dir)) {
        throw ApiError{http::status::conflict, "campaign file not read",
                       file.string() + " is a symbolic link to a file outside " + options.campaigns_dir.string() + ": not read",
                       "campaign"};
      }
      s.campaign = load_campaign(file);
      s.source = file.string();
    }
  } catch (const ApiError&) {
    throw;
  } catch (const std::exception& e) {  // cfg::Error, and anything a malformed file makes a loader throw
    throw ApiError{http::status::bad_request, "invalid campaign YAML", e.what()};
  }
  const std::string name = s.campaign.name;
  try {
    runner.start(std::move(s));
  } catch (const Conflict& e) {
    throw ApiError{http::status::conflict, "a campaign is running", e.what()};
  } catch (const InsufficientStorage& e) {
    throw ApiError{http::status::insufficient_storage, "no room for the record", e.what()};
  } catch (const BadField& e) {
    throw ApiError{http::status::bad_request, "cannot start", e.what(), e.field};
  } catch (const std::invalid_argument& e) {
    throw ApiError{http::status::bad_request, "cannot start", e.what()};
  }
  spdlog::info("campaign '{}' started", name);
  json reply = {{"started", name}, {"rig", rig}, {"status", runner.status()}};
  if (!warning.empty()) {
    spdlog::warn("{}", warning);
    reply["warning"] = warning;
  }
  return json_reply(http::status::accepted, reply);
}

Reply ApiServer::Impl::inject(const std::string& what, const json& body) {
  LoopRequest r;
  using K = LoopRequest::Kind;
  // Ranges are check_injection's (runner.hpp), checked in runner.inject: one table for every client.
  auto duration = [&] { return body.contains("duration_s") ? number_field(body, "duration_s") : 0.0; };
  if (what == "gap") {
    allow_fields(body, {"gap_deg", "programme"});
    if (field<bool>(body, "programme", false)) {
      r.kind = K::programme_gap;
    } else {
      r.kind = K::set_gap;
      r.value = units::deg_to_rad(number_field(body, "gap_deg"));
    }
  } else if (what == "sensor") {
    allow_fields(body, {"mode", "bias_kpa", "rms_kpa", "duration_s"});
    const std::string mode = field<std::string>(body, "mode", "");
    r.kind = K::sensor_fault;
    r.duration_s = duration();
    if (mode == "stuck") {
      r.sensor = SensorFault::stuck;
    } else if (mode == "dropout") {
      r.sensor = SensorFault::dropout;
    } else if (mode == "bias") {
      r.sensor = SensorFault::bias;
      r.value = number_field(body, "bias_kpa") * units::kPaPerKpa;
    } else if (mode == "noise") {
      r.sensor = SensorFault::noise;
      r.value = number_field(body, "rms_kpa") * units::kPaPerKpa;
      if (r.value < 0) throw ApiError{http::status::bad_request, "bad field", "'rms_kpa' must be >= 0"};
    } else {
      throw ApiError{http::status::bad_request, "bad field", "'mode' must be stuck, dropout, bias or noise"};
    }
  } else if (what == "drive") {
    allow_fields(body, {"mode", "on", "duration_s"});
    const std::string mode = field<std::string>(body, "mode", "ignore_commands");
    if (mode != "ignore_commands") throw ApiError{http::status::bad_request, "bad field", "'mode' must be ignore_commands"};
    r.kind = K::drive_fault;
    r.on = field<bool>(body, "on", true);
    r.duration_s = duration();
  } else if (what == "rig") {
    allow_fields(body, {"mode", "on"});
    const std::string mode = field<std::string>(body, "mode", "silent");
    if (mode != "silent") throw ApiError{http::status::bad_request, "bad field", "'mode' must be silent"};
    r.kind = K::rig_fault;
    r.on = field<bool>(body, "on", true);
  } else if (what == "clear") {
    allow_fields(body, {});
    r.kind = K::clear_faults;
  } else {
    const std::string hint = cfg::closest(what, {"gap", "sensor", "drive", "rig", "clear"});
    throw ApiError{
        http::status::not_found, "unknown injection",
        "'" + what + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)") + "; use gap, sensor, drive, rig or clear"};
  }
  try {
    runner.inject(r);
  } catch (const Conflict& e) {
    throw ApiError{http::status::conflict, "nothing to inject into", e.what()};
  } catch (const BadField& e) {  // a value outside check_injection's table
    throw ApiError{http::status::bad_request, "bad field", e.what(), e.field};
  } catch (const std::invalid_argument& e) {
    throw ApiError{http::status::bad_request, "not possible on this rig", e.what()};
  }
  return json_reply(http::status::accepted, {{"injected", what}, {"request", body}});
}

Reply ApiServer::Impl::runs() {
  json list = json::array();
  std::vector<std::filesystem::path> dirs;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(options.runs_dir, ec)) {
    if (is_run_dir(options.runs_dir, e.path().filename().string())) dirs.push_back(e.path());
  }
  std::sort(dirs.rbegin(), dirs.rend());  // newest first: names start with the UTC time
  for (const auto& d : dirs) {
    json j = {{"id", d.filename().string()}};
    try {
      const json r = record_of(d).to_json();
      for (const char* k : {"campaign", "run", "outcome", "reason", "start_utc", "stop_utc"}) j[k] = r[k];
      // The plant the run ran on (its recorded snapshot's file): the model its analyses default to.
      if (r.contains("config") && r["config"].is_object() && r["config"].value("plant_file", "") != "")
        j["plant"] = std::filesystem::path(r["config"].value("plant_file", "")).stem().string();
    } catch (const std::exception& e) {
      j["error"] = e.what();  // names the file, and the line and column
    }
    list.push_back(j);
  }
  return json_reply(http::status::ok, {{"runs", list}});
}

Reply ApiServer::Impl::run(const std::string& id) {
  const auto dir = options.runs_dir / id;
  if (!is_run_dir(options.runs_dir, id)) {
    throw ApiError{http::status::not_found, "unknown run", "'" + id + "' is not a run (GET /api/runs lists them)"};
  }
  json files = json::array();
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    std::error_code size_ec;
    const auto bytes = e.file_size(size_ec);
    if (plain_file(e) && !size_ec && cfg::plain_name(e.path().filename().string()) && e.path().extension() != ".tmp") {
      files.push_back({{"name", e.path().filename().string()}, {"bytes", bytes}});
    }
  }
  json r;
  try {
    r = read_json_inside(options.runs_dir, {id, "run.json"});
  } catch (const std::exception& e) {
    throw ApiError{http::status::unprocessable_entity, "unreadable run.json", e.what()};
  }
  if (r.is_object() && r.value("outcome", json()) == "running") {
    if (const auto end = runner.unrecorded_end(id)) r = end->record.to_json();
  }
  return json_reply(http::status::ok, {{"id", id}, {"files", files}, {"run", r}});
}

Reply ApiServer::Impl::run_events(const std::string& id, const Target& t) {
  if (!is_run_dir(options.runs_dir, id)) {
    throw ApiError{http::status::not_found, "unknown run", "'" + id + "' is not a run (GET /api/runs lists them)"};
  }
  const double offset = query_number(t, "offset", 0);
  if (!(offset >= 0 && offset <= 9.0e15 && offset == std::floor(offset)))
    throw ApiError{http::status::bad_request, "bad field", "'offset' must be a whole number of bytes >= 0", "offset"};
  try {
    return json_reply(http::status::ok, event_feed(options.runs_dir / id / "events.jsonl", static_cast<std::uint64_t>(offset)));
  } catch (const BadField& e) {
    throw ApiError{http::status::bad_request, "bad field", e.what(), e.field};
  }
}

Reply ApiServer::Impl::run_file(const std::string& id, const std::string& file) {
  const auto path = options.runs_dir / id / file;
  // A .tmp is an output being made (report.html.tmp): half of one is never served, as the run's
  // file list (run()) never shows one.
  if (!is_run_dir(options.runs_dir, id) || !cfg::plain_name(file) || path.extension() == ".tmp") {
    throw ApiError{http::status::not_found, "unknown file", "run '" + id + "' has no file '" + file + "'"};
  }
  Reply r = opened_file(options.runs_dir, {id, file}, "run '" + id + "' has no file '" + file + "'");
  const auto ext = path.extension().string();
  r.content_type = ext == ".csv"     ? "text/csv"
                   : ext == ".json"  ? "application/json"
                   : ext == ".jsonl" ? "application/x-ndjson"
                                     : "application/octet-stream";
  r.extra_header = "attachment; filename=\"" + file + "\"";
  return r;
}

std::filesystem::path ApiServer::Impl::ended_run(const std::string& id, RunRecord* record) const {
  const auto dir = options.runs_dir / id;
  if (!is_run_dir(options.runs_dir, id)) {
    throw ApiError{http::status::not_found, "unknown run", "'" + id + "' is not a run (GET /api/runs lists them)"};
  }
  RunRecord r;
  try {
    r = read_run_record_inside(dir);
  } catch (const std::exception& e) {
    throw ApiError{http::status::unprocessable_entity, "unreadable run.json", e.what()};
  }
  const auto end = r.outcome == Outcome::running ? runner.unrecorded_end(id) : std::nullopt;
  if (end && end->written) r = end->record;
  if (end && !end->written) {
    throw ApiError{http::status::conflict, "the run's record is not on disk",
                   "run '" + id +
                       "' has ended, but its final run.json could not be written, and a review reads that file; "
                       "free room in the runs folder and ask again (GET /api/runs/" +
                       id + " shows the end)"};
  }
  if (r.outcome == Outcome::running) {
    throw ApiError{http::status::conflict, "the run is still running",
                   "run '" + id + "' is reviewed once it has ended; abort or stop it, or wait"};
  }
  if (record != nullptr) *record = std::move(r);
  return dir;
}

Reply ApiServer::Impl::run_report(const std::string& id, const Target& t, bool head) {
  // ?wait= is 0 or 1: any other value (wait=false, wait=no) waited, the opposite of what it says.
  const auto wait = t.query.find("wait");
  if (wait != t.query.end() && wait->second != "0" && wait->second != "1") {
    throw ApiError{http::status::bad_request, "bad field",
                   "'wait' must be 0 (answer 202 at once) or 1 (wait for the report), got '" + printable(wait->second, 40) + "'",
                   "wait"};
  }
  const auto dir = ended_run(id);
  try {
    refuse_linked_run_files(dir);
  } catch (const std::exception& e) {
    throw ApiError{http::status::unprocessable_entity, "file not read", e.what()};
  }
  // Made once per run, on the job worker, and kept in its folder (analyses.hpp run_report_current).
  if (run_report_current(dir)) return html_file(options.runs_dir, {id, "report.html"});
  if (head) {
    // HEAD asks for the header fields, not for the report: making one (seconds for an hour's run,
    // a place in the job queue, a file written) only to drop its body is work nobody asked for.
    // Its length is not known before it is made, and HEAD may leave Content-Length out (RFC 9110
    // 9.3.2); a wrong one (0) would tell the client the report is empty. ?wait=0 changes nothing:
    // no job is queued, so there is none to answer with.
    Reply r = html_file({}, {});
    r.length_unknown = true;
    return r;
  }
  std::optional<JobStatus> job = jobs.find(id, "report");
  if (job && (job->state == JobState::done || job->state == JobState::failed)) {
    jobs.forget(id, "report");  // a failure is answered once; the next request tries again
    if (job->state == JobState::failed) throw ApiError{http::status::unprocessable_entity, "cannot make the report", job->error};
    job.reset();
  }
  if (!job) {
    JobStatus s;
    s.run = id;
    s.id = "report";
    s.kind = "report";
    try {
      // Stops between chunks of rows when the server stops (an hour's run takes seconds to read).
      job = jobs.submit(s, [dir](const JobQueue::Progress& progress, const std::atomic<bool>& cancel) {
        return make_run_report(dir, progress, &cancel);
      });
    } catch (const JobRefused& e) {
      throw ApiError{http::status::service_unavailable, "cannot queue the job", e.what()};
    }
  }
  Reply reply = json_reply(http::status::accepted, {{"report", job->to_json()}});
  if (wait != t.query.end() && wait->second == "0") return reply;
  auto w = std::make_shared<JobWait>();
  w->run = id;
  w->id = "report";
  w->then = [this, dir, id](const JobStatus& s) -> Reply {
    if (s.state == JobState::done && std::filesystem::exists(dir / "report.html"))
      return html_file(options.runs_dir, {id, "report.html"});
    jobs.forget(id, "report");
    return error_reply(http::status::unprocessable_entity, "cannot make the report", s.error);
  };
  reply.wait = std::move(w);
  return reply;
}

Reply ApiServer::Impl::models() {
  const json list = listing(model_listings, options.plant_dir, [](const std::filesystem::path& file, json& j) {
    const cfg::Node root = cfg::Node::load_file(file);  // read once: checked as a plant, then its description
    (void)plant::Plant::from_yaml(root);
    j["description"] = root.text("description", "");
  });
  return json_reply(http::status::ok, {{"models", list}, {"kinds", {kAnalysisKinds[0], kAnalysisKinds[1]}}});
}

std::optional<json> ApiServer::Impl::find_analysis(const std::string& id, const std::string& aid) const {
  if (const auto job = jobs.find(id, aid); job && job->kind != "report" && job->state != JobState::done) return job->to_json();
  for (auto& a : finished_analyses(options.runs_dir / id)) {
    if (a.value("id", "") == aid) return a;
  }
  return std::nullopt;
}

namespace {

// What every analysis in a list or alone carries: where its report is, once there is one.
json with_links(json a, const std::string& run) {
  const std::string base = "/api/runs/" + run + "/analyses/" + a.value("id", "");
  a["run"] = run;
  a["url"] = base;
  if (a.value("state", "") == "done") a["report"] = base + "/report.html";
  return a;
}

}  // namespace

Reply ApiServer::Impl::analyses(const std::string& id) {
  const auto dir = options.runs_dir / id;
  if (!is_run_dir(options.runs_dir, id)) {
    throw ApiError{http::status::not_found, "unknown run", "'" + id + "' is not a run (GET /api/runs lists them)"};
  }
  json list = json::array();
  std::vector<std::string> on_disk;
  for (auto& a : finished_analyses(dir)) {
    on_disk.push_back(a.value("id", ""));
    list.push_back(with_links(std::move(a), id));
  }
  for (const auto& job : jobs.of_run(id)) {
    if (job.kind == "report" || std::find(on_disk.begin(), on_disk.end(), job.id) != on_disk.end()) continue;
    list.push_back(with_links(job.to_json(), id));
  }
  return json_reply(http::status::ok, {{"run", id}, {"analyses", list}});
}

Reply ApiServer::Impl::start_analysis(const std::string& id, const Request& req) {
  if (const std::string why = refusing(); !why.empty())
    throw ApiError{http::status::service_unavailable, "not accepting jobs", why};
  // The body first: a malformed request is named whatever the run.
  const json body = parse_json_body(req);
  allow_fields(body, {"kind", "model"});
  const std::string kind = field<std::string>(body, "kind", "");
  const std::vector<std::string> kinds(std::begin(kAnalysisKinds), std::end(kAnalysisKinds));
  if (std::find(kinds.begin(), kinds.end(), kind) == kinds.end()) {
    const std::string hint = kind.empty() ? "" : cfg::closest(kind, kinds);
    throw ApiError{http::status::bad_request, "bad field",
                   "'kind' must be compare or diagnose" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)"), "kind"};
  }
  const std::string model = field<std::string>(body, "model", "");
  const auto names = yaml_stems(options.plant_dir);
  if (model.empty()) {
    throw ApiError{http::status::bad_request, "bad field", "'model' is required: a plant model's name from GET /api/models",
                   "model"};
  }
  if (!cfg::plain_name(model) || std::find(names.begin(), names.end(), model) == names.end()) {
    const std::string hint = cfg::closest(model, names);
    throw ApiError{http::status::not_found, "unknown model",
                   "'model': '" + model + "' is not a plant model in " + options.plant_dir.string() +
                       (hint.empty() ? "" : " (did you mean '" + hint + "'?)"),
                   "model"};
  }
  const auto model_file = options.plant_dir / (model + ".yaml");
  if (!resolves_inside(model_file, options.plant_dir)) {
    throw ApiError{http::status::conflict, "model file not read",
                   "'model': " + model_file.string() + " is a symbolic link to a file outside " + options.plant_dir.string() +
                       ": not read (the bench reads and quotes no file outside its folders)",
                   "model"};
  }
  const auto dir = ended_run(id);
  if (!std::filesystem::is_regular_file(dir / "telemetry.csv")) {
    throw ApiError{http::status::unprocessable_entity, "no measurement", "run '" + id + "' has no telemetry.csv"};
  }
  try {
    refuse_linked_run_files(dir);
  } catch (const std::exception& e) {
    throw ApiError{http::status::unprocessable_entity, "file not read", e.what()};
  }
  if (kind == "diagnose") {
    std::error_code ec;
    const std::uint64_t csv_bytes = std::filesystem::file_size(dir / "telemetry.csv", ec);
    const std::uint64_t need = ec ? 0 : diagnose_memory_bytes(csv_bytes);
    if (need > options.max_diagnose_bytes) {
      const auto mb = [](std::uint64_t bytes) { return std::to_string(std::llround(bytes / 1048576.0)) + " MB"; };
      throw ApiError{http::status::unprocessable_entity, "too large for this server",
                     "run '" + id + "': a diagnosis of its telemetry.csv (" + mb(csv_bytes) + ") holds about " + mb(need) +
                         " in memory, locked while it runs; this server allows " + mb(options.max_diagnose_bytes) +
                         " (hilbench serve --max-diagnose-mb). A compare reads it in chunks and has no such limit; "
                         "or run hilbench diagnose --data on a copy of the run's folder elsewhere"};
    }
  }
  // The same analysis already waiting or running: that one is the answer, not a second copy.
  std::vector<std::string> live;
  for (const auto& job : jobs.of_run(id)) {
    if (job.state != JobState::queued && job.state != JobState::running) continue;
    if (job.kind == kind && job.model == model) {
      return json_reply(http::status::accepted, {{"analysis", with_links(job.to_json(), id)},
                                                 {"note", "the same analysis is already " + std::string(to_string(job.state))}});
    }
    live.push_back(job.id);
  }
  AnalysisSpec spec;
  spec.run_dir = dir;
  spec.kind = kind;
  spec.model = model;
  spec.model_file = std::filesystem::absolute(model_file);
  spec.model_dir = std::filesystem::absolute(options.plant_dir);
  spec.id = next_analysis_id(dir, kind, model, live);
  JobStatus s;
  s.run = id;
  s.id = spec.id;
  s.kind = kind;
  s.model = model;
  JobStatus queued;
  try {
    queued = jobs.submit(s, [spec](const JobQueue::Progress& progress, const std::atomic<bool>& cancel) {
      return run_analysis(spec, progress, &cancel);
    });
  } catch (const JobRefused& e) {
    throw ApiError{http::status::service_unavailable, "cannot queue the job", e.what()};
  }
  spdlog::info("run {}: {} against {} queued as {}", id, kind, model, spec.id);
  return json_reply(http::status::accepted, {{"analysis", with_links(queued.to_json(), id)}});
}

Reply ApiServer::Impl::analysis(const std::string& id, const std::string& aid) {
  const auto a = cfg::plain_name(id) && cfg::plain_name(aid) ? find_analysis(id, aid) : std::nullopt;
  if (!a) {
    throw ApiError{http::status::not_found, "unknown analysis",
                   "run '" + id + "' has no analysis '" + aid + "' (GET /api/runs/" + id + "/analyses lists them)"};
  }
  return json_reply(http::status::ok, {{"analysis", with_links(*a, id)}});
}

Reply ApiServer::Impl::analysis_file(const std::string& id, const std::string& aid, const std::string& file) {
  const auto a = cfg::plain_name(id) && cfg::plain_name(aid) ? find_analysis(id, aid) : std::nullopt;
  if (!a) {
    throw ApiError{http::status::not_found, "unknown analysis",
                   "run '" + id + "' has no analysis '" + aid + "' (GET /api/runs/" + id + "/analyses lists them)"};
  }
  const std::string state = a->value("state", "");
  if (state == "queued" || state == "running") return json_reply(http::status::accepted, {{"analysis", with_links(*a, id)}});
  if (state != "done") throw ApiError{http::status::unprocessable_entity, "the analysis failed", a->value("error", "")};
  const auto path = analysis_dir(options.runs_dir / id, aid) / file;
  const std::string missing = "analysis '" + aid + "' of run '" + id + "' has no file '" + file + "'";
  if (!cfg::plain_name(file)) throw ApiError{http::status::not_found, "unknown file", missing};
  const std::vector<std::string> parts = {id, "analyses", aid, file};
  if (path.extension() == ".html") return html_file(options.runs_dir, parts);
  Reply r = opened_file(options.runs_dir, parts, missing);
  r.content_type = path.extension() == ".json"   ? "application/json"
                   : path.extension() == ".yaml" ? "application/yaml"
                                                 : "text/plain";
  r.extra_header = "attachment; filename=\"" + file + "\"";
  return r;
}

namespace {

Reply route_index();

// The endpoints, one row each: the method, the path ("{name}" matches one segment, handed to the
// handler in order), what it does (GET /api lists this table), and the handler.
struct Route {
  http::verb method;
  std::string_view path;
  std::string_view summary;
  Reply (*handle)(ApiServer::Impl& api, const Request& req, const Target& t, const std::vector<std::string>& args);
  std::vector<std::string> query = {};  // the query options it takes; `token` (authorised()) is every route's
};

const Route kRoutes[] = {
    {http::verb::get, "/", "the operator console: live plots, loop health, events, controls, runs (HTML)",
     [](ApiServer::Impl&, const Request&, const Target&, const std::vector<std::string>&) {
       Reply r = body_reply(http::status::ok, std::string(console::kPage), "text/html; charset=utf-8");
       r.no_store = true;
       return r;
     }},
    {http::verb::get, "/favicon.ico", "no icon: 204, so that a browser asking for one is not an error",
     [](ApiServer::Impl&, const Request&, const Target&, const std::vector<std::string>&) {
       return body_reply(http::status::no_content, "", "image/x-icon");
     }},
    {http::verb::get, "/api", "this list",
     [](ApiServer::Impl&, const Request&, const Target&, const std::vector<std::string>&) { return route_index(); }},
    {http::verb::get, "/api/health", "the server answers, and its version",
     [](ApiServer::Impl& api, const Request&, const Target&, const std::vector<std::string>&) {
       return json_reply(http::status::ok, {{"ok", true}, {"version", api.options.version}});
     }},
    {http::verb::get, "/api/campaigns", "the campaign files the server can run",
     [](ApiServer::Impl& api, const Request&, const Target&, const std::vector<std::string>&) { return api.campaigns(); }},
    {http::verb::get, "/api/rigs", "the rig files",
     [](ApiServer::Impl& api, const Request&, const Target&, const std::vector<std::string>&) { return api.rigs(); }},
    {http::verb::get, "/api/models", "the plant models a run can be analysed against",
     [](ApiServer::Impl& api, const Request&, const Target&, const std::vector<std::string>&) { return api.models(); }},
    {http::verb::get, "/api/status", "the campaign running now, its loop's health and interlocks",
     [](ApiServer::Impl& api, const Request&, const Target&, const std::vector<std::string>&) {
       return json_reply(http::status::ok, api.runner.status());
     }},
    {http::verb::post,
     "/api/start",
     "start a campaign: {campaign | campaign_yaml, rig, runs, speed}",
     [](ApiServer::Impl& api, const Request& req, const Target& t, const std::vector<std::string>&) { return api.start(req, t); },
     {"rig", "runs", "speed"}},
    {http::verb::post, "/api/stop", "end the campaign after the run's current period",
     [](ApiServer::Impl& api, const Request&, const Target&, const std::vector<std::string>&) { return api.stop(); }},
    {http::verb::post, "/api/abort", "safe state now, then end the campaign: {reason}",
     [](ApiServer::Impl& api, const Request& req, const Target&, const std::vector<std::string>&) { return api.abort(req); }},
    {http::verb::post, "/api/inject/{kind}", "inject a gap change or a fault: gap, sensor, drive, rig, clear",
     [](ApiServer::Impl& api, const Request& req, const Target&, const std::vector<std::string>& a) {
       return api.inject(a[0], parse_json_body(req));
     }},
    {http::verb::get, "/api/runs", "the recorded runs, newest first",
     [](ApiServer::Impl& api, const Request&, const Target&, const std::vector<std::string>&) { return api.runs(); }},
    {http::verb::get, "/api/runs/{id}", "a run's record and its files",
     [](ApiServer::Impl& api, const Request&, const Target&, const std::vector<std::string>& a) { return api.run(a[0]); }},
    {http::verb::get,
     "/api/runs/{id}/report.html",
     "a run's paper-style report (HTML, made on the job worker once the run has ended; ?wait=0: 202 and the job's state until "
     "made)",
     [](ApiServer::Impl& api, const Request& req, const Target& t, const std::vector<std::string>& a) {
       return api.run_report(a[0], t, req.method() == http::verb::head);
     },
     {"wait"}},
    {http::verb::get, "/api/runs/{id}/analyses", "a run's analyses against plant models: queued, running, done or failed",
     [](ApiServer::Impl& api, const Request&, const Target&, const std::vector<std::string>& a) { return api.analyses(a[0]); }},
    {http::verb::post, "/api/runs/{id}/analyses", "analyse an ended run against a plant model: {kind: compare | diagnose, model}",
     [](ApiServer::Impl& api, const Request& req, const Target&, const std::vector<std::string>& a) {
       return api.start_analysis(a[0], req);
     }},
    {http::verb::get, "/api/runs/{id}/analyses/{analysis}", "one analysis: its state, progress, error or result",
     [](ApiServer::Impl& api, const Request&, const Target&, const std::vector<std::string>& a) {
       return api.analysis(a[0], a[1]);
     }},
    {http::verb::get, "/api/runs/{id}/analyses/{analysis}/{file}",
     "a file of a finished analysis: report.html, compare.json or diagnosis.json, fitted_model.yaml, analysis.json",
     [](ApiServer::Impl& api, const Request&, const Target&, const std::vector<std::string>& a) {
       return api.analysis_file(a[0], a[1], a[2]);
     }},
    {http::verb::get,
     "/api/runs/{id}/events",
     "a run's events from byte ?offset=N of events.jsonl (0 when not given): operator events whole, loop statistics "
     "summarised per second; follow next_offset",
     [](ApiServer::Impl& api, const Request&, const Target& t, const std::vector<std::string>& a) {
       return api.run_events(a[0], t);
     },
     {"offset"}},
    {http::verb::get, "/api/runs/{id}/{file}", "one file of a run",
     [](ApiServer::Impl& api, const Request&, const Target&, const std::vector<std::string>& a) {
       return api.run_file(a[0], a[1]);
     }},
    {http::verb::get,
     "/api/telemetry",
     "live telemetry: a WebSocket, ?rate_hz=N",
     [](ApiServer::Impl&, const Request&, const Target&, const std::vector<std::string>&) -> Reply {
       throw ApiError{http::status::upgrade_required, "WebSocket only", "GET /api/telemetry?rate_hz=N with a WebSocket upgrade"};
     },
     {"rate_hz"}},
};

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
  for (const auto& r : kRoutes) {
    if (!out.empty()) out += ", ";
    out += std::string(http::to_string(r.method)) + " " + std::string(r.path);
  }
  return out;
}

Reply route_index() {
  json list = json::array();
  for (const auto& r : kRoutes) {
    list.push_back({{"method", std::string(http::to_string(r.method))},
                    {"path", std::string(r.path)},
                    {"summary", std::string(r.summary)},
                    {"query", r.query}});
  }
  return json_reply(http::status::ok, {{"endpoints", list}});
}

// The kRoutes row of `pattern` (one that is there: a programming error otherwise).
const Route& route_of(std::string_view pattern) {
  for (const auto& r : kRoutes) {
    if (r.path == pattern) return r;
  }
  throw std::logic_error("no route " + std::string(pattern));
}

// A query option the route does not take is refused by name, as an unknown body field is: ignored,
// a typo (?wiat=0, ?rate=5000, ?run=) did what was not asked without a word. So is one given twice
// (?rate_hz=1&rate_hz=5000 streamed at the last one). One check for every route, the telemetry
// WebSocket's included.
void refuse_unknown_query(const Target& t, const Route& r) {
  if (!t.repeated.empty()) {
    const std::string shown = loggable_target(t.repeated.front());
    throw ApiError{http::status::bad_request, "query option given twice", "'" + shown + "' is given more than once", shown};
  }
  std::vector<std::string> names = r.query;
  names.emplace_back("token");
  std::string takes;
  for (const auto& name : r.query) takes += name + ", ";
  const std::string after = "; " + std::string(r.path) + " takes " +
                            (takes.empty() ? "no query option" : takes.substr(0, takes.size() - 2)) + " (and token)";
  for (const auto& item : t.query) refuse_unknown(item.first, loggable_target(item.first), names, "unknown query option", after);
}

}  // namespace

Reply ApiServer::Impl::handle(const Request& req, const Target& t) {
  std::vector<std::string> args;
  std::string allow;  // the methods the path takes, for a 405
  for (const auto& r : kRoutes) {
    if (!match(r.path, t.path, args)) continue;
    // HEAD is GET without the body (RFC 9110 9.3.2): the same route, the same header fields.
    const bool head_of_get = req.method() == http::verb::head && r.method == http::verb::get;
    if (r.method == req.method() || head_of_get) {
      refuse_unknown_query(t, r);
      return r.handle(*this, req, t, args);
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

Reply ApiServer::Impl::stop() {
  try {
    runner.stop();
  } catch (const Conflict& e) {
    throw ApiError{http::status::conflict, "nothing to stop", e.what()};
  }
  return json_reply(http::status::accepted, {{"stopping", true}});
}

Reply ApiServer::Impl::abort(const Request& req) {
  const json body = parse_json_body(req);
  allow_fields(body, {"reason"});
  const std::string given = field<std::string>(body, "reason", "no reason given");
  // The reason goes as it is into the server log, run.json and the console: a newline or an escape
  // sequence in it forged whole log lines ("[info] campaign ... started") and drove the terminal
  // of whoever read the log. C1 controls (U+0080..U+009F: 0xC2 0x80..0x9F in UTF-8) included.
  constexpr std::size_t kMaxReasonBytes = 500;
  bool control = false;
  for (std::size_t i = 0; i < given.size(); ++i) {
    const auto c = static_cast<unsigned char>(given[i]);
    const auto next = i + 1 < given.size() ? static_cast<unsigned char>(given[i + 1]) : 0;
    control = control || c < 0x20 || c == 0x7f || (c == 0xc2 && next >= 0x80 && next <= 0x9f);
  }
  if (control || given.size() > kMaxReasonBytes) {
    throw ApiError{http::status::bad_request, "bad field",
                   "'reason' must be one line of at most " + std::to_string(kMaxReasonBytes) +
                       " bytes without control characters, got '" + printable(given, 60) + "'",
                   "reason"};
  }
  const std::string reason = "operator abort: " + given;
  std::string ends_with;
  try {
    ends_with = runner.abort(reason);
  } catch (const Conflict& e) {
    throw ApiError{http::status::conflict, "nothing to abort", e.what()};
  }
  json answer = {{"aborting", true}, {"reason", ends_with}};
  if (ends_with != reason) answer["note"] = "an abort was already under way; the campaign ends with its reason";
  return json_reply(http::status::accepted, answer);
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
      if (!websocket::is_upgrade(req) && target.path.size() >= 2 && target.path[0] == "api" && target.path[1] == "runs")
        return answer_on_files_thread(std::move(req), target);
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

  // A request under /api/runs reads run folders: answered on the run files' thread
  // (Impl::files), sent from here. The connection waits; the io thread does not.
  void answer_on_files_thread(Request req, const Target& target) {
    const bool keep_alive = req.keep_alive();
    auto asked = std::make_shared<const std::pair<Request, Target>>(std::move(req), target);
    asio::post(api_->files, [self = shared_from_this(), asked, keep_alive] {
      Reply reply;
      try {
        reply = self->api_->answer(asked->first, asked->second);
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
    std::make_shared<WsSession>(stream_.release_socket(), std::move(buffer_), api_->hub, foxglove, api_->session_id,
                                std::move(slot_), ConnectionSlot(api_->open_streams), api_->options.ws_idle_timeout)
        ->run(std::move(req), rate_hz);
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

void ApiServer::Impl::accept() {
  acceptor.async_accept(asio::make_strand(io), [self = shared_from_this()](beast::error_code ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted) return;
    if (ec) return self->accept();
    if (*self->open_connections >= kMaxConnections && !self->evict_longest_idle()) {
      // Every connection is busy (WebSocket streams, requests being served): this one is closed
      // at once, no read, no reply to build; said in the log at most once a minute.
      beast::error_code ignored;
      socket.close(ignored);
      const auto now = std::chrono::steady_clock::now();
      if (now - self->last_refusal_logged > std::chrono::minutes(1)) {
        spdlog::warn("{} connections are open and none is idle: refusing more until some close", kMaxConnections);
        self->last_refusal_logged = now;
      }
      return self->accept();
    }
    auto session = std::make_shared<HttpSession>(std::move(socket), self);
    if (self->http_sessions.size() >= 2 * kMaxConnections)
      std::erase_if(self->http_sessions, [](const auto& w) { return w.expired(); });
    self->http_sessions.push_back(session);
    session->read();
    self->accept();
  });
}

// At the connection cap, the connection that has waited longest for a request gives its place to
// the newcomer: a flood of idle sockets (256 of them) otherwise locked the operator out until they
// closed or the 60 s idle timeout ended them, in the middle of a run that may need an abort.
// False when no connection waits (all stream telemetry or are being served).
bool ApiServer::Impl::evict_longest_idle() {
  std::erase_if(http_sessions, [](const auto& w) { return w.expired(); });
  std::shared_ptr<HttpSession> oldest;
  for (const auto& w : http_sessions) {
    const auto s = w.lock();
    if (s && s->idle_since() && (!oldest || *s->idle_since() < *oldest->idle_since())) oldest = s;
  }
  if (!oldest) return false;
  oldest->evict();
  const auto now = std::chrono::steady_clock::now();
  if (now - last_refusal_logged > std::chrono::minutes(1)) {
    spdlog::warn("{} connections are open: closing the longest idle one for each new one", kMaxConnections);
    last_refusal_logged = now;
  }
  return true;
}

ApiServer::ApiServer(asio::io_context& io, ApiOptions options, CampaignRunner& runner, TelemetryHub& hub) {
  beast::error_code ec;
  const auto address = asio::ip::make_address(options.address, ec);
  if (ec) throw std::invalid_argument("--listen: '" + options.address + "' is not an IP address");
  loopback_ = address.is_loopback();
  if (!options.token.empty()) {
    // A token is one printable word: a blank one would let '?token=%20' in, and one with spaces
    // or control characters cannot travel in a header intact.
    const bool printable =
        std::all_of(options.token.begin(), options.token.end(), [](char ch) { return ch > 0x20 && ch < 0x7f; });
    if (!printable) {
      throw std::invalid_argument("the token must be printable ASCII without spaces (got " +
                                  std::to_string(options.token.size()) + " characters that are not)");
    }
    if (options.token.size() < 8) throw std::invalid_argument("the token must have at least 8 characters");
  }
  if (!loopback_ && options.token.empty()) {
    throw std::invalid_argument("listening on " + options.address +
                                " (not loopback) requires a token: --token T or HILBENCH_TOKEN; every request must then carry "
                                "'Authorization: Bearer T'");
  }
  impl_ = std::make_shared<Impl>(io, std::move(options), runner, hub);
  if (const auto removed = remove_job_leftovers(impl_->options.runs_dir))
    spdlog::warn("removed {} half-made reports or analyses a previous server left in {}", removed,
                 impl_->options.runs_dir.string());
  const tcp::endpoint endpoint(address, impl_->options.port);
  auto& a = impl_->acceptor;
  a.open(endpoint.protocol());
  a.set_option(asio::socket_base::reuse_address(true));
  a.bind(endpoint, ec);
  if (ec)
    throw std::runtime_error("cannot listen on " + impl_->options.address + ":" + std::to_string(impl_->options.port) + ": " +
                             ec.message());
  a.listen(asio::socket_base::max_listen_connections);
  impl_->guard.emplace(impl_->options.address, a.local_endpoint().port(), impl_->options.allow_hosts);
  impl_->accept();
}

ApiServer::~ApiServer() {
  if (impl_) {
    beast::error_code ec;
    impl_->acceptor.close(ec);
    impl_->files.stop();  // what waits is dropped; what runs is a bounded read
    impl_->files.join();
    stop_jobs();
  }
}

void ApiServer::stop_jobs() { impl_->jobs.stop("the server is shutting down"); }

void ApiServer::cancel_jobs() { impl_->jobs.cancel("the server is shutting down"); }

unsigned short ApiServer::port() const { return impl_->acceptor.local_endpoint().port(); }

ApiServer::RawAnswer ApiServer::answer_raw(std::string_view bytes) {
  // The session's parser with the session's limits, fed from memory instead of a socket.
  http::request_parser<http::string_body> parser;
  parser.body_limit(impl_->options.max_body_bytes);
  parser.header_limit(16 * 1024);
  parser.eager(true);
  beast::error_code ec;
  std::size_t used = 0;
  while (!ec && used < bytes.size() && !parser.is_done()) {
    const std::size_t n = parser.put(asio::buffer(bytes.data() + used, bytes.size() - used), ec);
    if (n == 0 && !ec) break;
    used += n;
  }
  if (!ec && !parser.is_done()) ec = http::error::partial_message;
  Reply reply;
  if (ec) {
    reply = impl_->parse_failure(ec);
  } else {
    const Request req = parser.release();
    if (auto refused = impl_->refused_header(req)) {
      reply = std::move(*refused);
    } else {
      reply = impl_->answer(req, parse_target(std::string_view(req.target().data(), req.target().size())));
    }
  }
  return {static_cast<int>(reply.status), reply.file.empty() ? reply.body : "file: " + reply.file.string(), reply.content_type};
}

void ApiServer::refuse_starts(const std::string& why) {
  std::lock_guard lock(impl_->refuse_mutex);
  impl_->refuse_starts = why;
}

}  // namespace hil::bench
