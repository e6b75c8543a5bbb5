#include "telemetry_stream.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <map>
#include <unordered_map>
#include <variant>

#include <boost/asio/post.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <spdlog/spdlog.h>

#include "api_router.hpp"
#include "foxglove.hpp"

namespace hil::bench {
namespace api {
namespace {

namespace asio = boost::asio;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;

constexpr std::size_t kWsQueueLimit = 1024;  // telemetry messages per client; beyond: dropped and counted
constexpr std::size_t kWsRepliesLimit = 64;  // the session's own messages per client (answers to its requests)

const FieldSpecs kTelemetryQuery = {{"rate_hz", FieldType::number, "rows per second", 0, 5000, true, "20 when not given"}};

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

double telemetry_rate_hz(const Target& t) { return query_number(t, spec_of(route_of("/api/telemetry").query, "rate_hz"), 20); }

std::vector<Route> telemetry_routes() {
  return {
      {220, http::verb::get, "/api/telemetry", "live telemetry: a WebSocket, ?rate_hz=N",
       [](const Call&) -> Reply {
         throw ApiError{http::status::upgrade_required, "WebSocket only",
                        "GET /api/telemetry?rate_hz=N with a WebSocket upgrade"};
       },
       kTelemetryQuery},
  };
}

}  // namespace api

using namespace api;

// ---------------------------------------------------------------------------------------------
// WebSocket session: accepts the upgrade, then writes telemetry. A plain session reads only to
// notice the close; a Foxglove session also takes the client's subscribe/unsubscribe.

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

namespace api {

void start_telemetry_stream(tcp::socket&& socket, beast::flat_buffer read_ahead, TelemetryHub& hub, bool foxglove,
                            std::string session_id, ConnectionSlot slot, ConnectionSlot stream_slot,
                            std::chrono::milliseconds idle_timeout, Request req, double rate_hz) {
  std::make_shared<WsSession>(std::move(socket), std::move(read_ahead), hub, foxglove, std::move(session_id), std::move(slot),
                              std::move(stream_slot), idle_timeout)
      ->run(std::move(req), rate_hz);
}

}  // namespace api
}  // namespace hil::bench
