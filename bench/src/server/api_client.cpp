#include "hil/bench/server/api_client.hpp"

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

#include "hil/text_file.hpp"
#include "request_guard.hpp"

namespace hil::bench {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;

}  // namespace

nlohmann::json ApiReply::json() const {
  // The server's replies nest a run.json (at most 64 levels) in a few of their own.
  constexpr std::size_t kMaxDepth = 128;
  if (const auto at = too_deep(body, kMaxDepth))
    throw std::runtime_error("HTTP " + std::to_string(status) + " with JSON nested deeper than " + std::to_string(kMaxDepth) +
                             " levels (at byte " + std::to_string(*at + 1) + "): not parsed");
  try {
    return nlohmann::json::parse(body);
  } catch (const nlohmann::json::exception&) {
    throw std::runtime_error("HTTP " + std::to_string(status) + " with a body that is not JSON: " + body.substr(0, 200));
  }
}

ApiClient::ApiClient(const std::string& url, std::string token, std::chrono::milliseconds timeout)
    : token_(std::move(token)), timeout_(timeout) {
  std::string rest = url;
  if (rest.rfind("http://", 0) == 0) rest = rest.substr(7);
  if (rest.rfind("https://", 0) == 0) throw std::invalid_argument("https is not supported: " + url);
  if (const auto slash = rest.find('/'); slash != std::string::npos) rest = rest.substr(0, slash);
  const auto colon = rest.rfind(':');
  if (colon == std::string::npos) {
    host_ = rest;
    port_ = "8470";
  } else {
    host_ = rest.substr(0, colon);
    port_ = rest.substr(colon + 1);
  }
  if (host_.empty() || port_.empty()) throw std::invalid_argument("server URL '" + url + "' is not http://HOST:PORT");
}

namespace {

// Runs one asynchronous operation to its end. Beast's tcp_stream timeouts only apply to
// asynchronous operations, so the client is synchronous on top of them.
// Runs until that operation's handler has run, not until the io_context is out of work: the
// telemetry stream's WebSocket keeps a timer of its own (its idle rule, its pings) armed for good.
template <class Start>
void run_op(asio::io_context& io, Start&& start) {
  beast::error_code result;
  bool done = false;
  start([&](beast::error_code ec, auto&&...) {
    result = ec;
    done = true;
  });
  io.restart();
  while (!done) {
    if (io.run_one() == 0) {
      if (done) break;
      throw std::logic_error("the client's operation has no work left and did not complete");
    }
  }
  if (result) throw boost::system::system_error(result);
}

beast::tcp_stream connect(asio::io_context& io, const std::string& host, const std::string& port,
                          std::chrono::milliseconds timeout) {
  beast::tcp_stream stream(io);
  try {
    tcp::resolver resolver(io);
    // "[::1]" is the URL's and the Host header's spelling; the resolver takes the address alone.
    const bool bracketed = host.size() > 2 && host.front() == '[' && host.back() == ']';
    const auto endpoints = resolver.resolve(bracketed ? host.substr(1, host.size() - 2) : host, port);
    stream.expires_after(timeout);
    run_op(io, [&](auto handler) { stream.async_connect(endpoints, handler); });
  } catch (const boost::system::system_error& e) {
    throw ApiUnreachable("cannot reach the bench server at " + host + ":" + port + ": " + e.code().message());
  }
  return stream;
}

// host: "HOST:PORT", as the server checks it (a Host without its port is port 80's, and refused).
template <class Request>
void authorise(Request& req, const std::string& host, const std::string& token) {
  req.set(http::field::host, host);
  req.set(http::field::user_agent, "hilbench-ctl");
  if (!token.empty()) req.set(http::field::authorization, "Bearer " + token);
}

}  // namespace

constexpr std::uint64_t kMaxReplyBytes = 64ull << 20;

ApiReply ApiClient::request(const std::string& method, const std::string& target, const std::string& body,
                            const std::string& content_type) const {
  asio::io_context io;
  auto stream = connect(io, host_, port_, timeout_);
  http::request<http::string_body> req(http::string_to_verb(method), target, 11);
  authorise(req, host_ + ":" + port_, token_);
  if (!body.empty() || method == "POST") {
    req.set(http::field::content_type, content_type);
    req.body() = body;
  }
  req.prepare_payload();
  ApiReply reply;
  try {
    stream.expires_after(timeout_);
    run_op(io, [&](auto handler) { http::async_write(stream, req, handler); });
    beast::flat_buffer buffer;
    http::response_parser<http::string_body> parser;
    // The server's largest JSON reply (a long run list) is a few MB; a peer that sends more, or
    // announces more, is no hilbench server: refused at this size, not read until memory ends.
    parser.body_limit(kMaxReplyBytes);
    stream.expires_after(timeout_);
    // The header first: Beast 1.74's string body reserves the announced length as the body
    // begins, before its own limit is checked (a reply announcing 100 GB was std::bad_alloc).
    run_op(io, [&](auto handler) { http::async_read_header(stream, buffer, parser, handler); });
    if (const auto announced = parser.content_length(); announced && *announced > kMaxReplyBytes) {
      throw ApiUnreachable(method + " " + target + " at " + host_ + ":" + port_ + ": the reply announces " +
                           std::to_string(*announced) + " bytes, more than a hilbench server sends (" +
                           std::to_string(kMaxReplyBytes >> 20) + " MiB at most): body limit exceeded");
    }
    run_op(io, [&](auto handler) { http::async_read(stream, buffer, parser, handler); });
    const auto& res = parser.get();
    reply.status = res.result_int();
    reply.body = res.body();
    reply.content_type = std::string(res[http::field::content_type]);
  } catch (const boost::system::system_error& e) {
    throw ApiUnreachable(method + " " + target + " at " + host_ + ":" + port_ + ": " + e.code().message());
  }
  beast::error_code ec;
  stream.socket().shutdown(tcp::socket::shutdown_both, ec);
  return reply;
}

ApiReply ApiClient::get(const std::string& target) const { return request("GET", target, "", ""); }

ApiReply ApiClient::post(const std::string& target, const nlohmann::json& body) const {
  return request("POST", target, body.dump(), "application/json");
}

namespace {

// Beast's file keeping the error of a failed write: a download cut because the local disk took no
// more is the local file's failure, not the server's nor the network's ("GET ... at HOST:PORT: No
// space left on device" read as the server's disk).
class LocalFile : public beast::file {
 public:
  std::size_t write(const void* data, std::size_t bytes, beast::error_code& ec) {
    const std::size_t written = beast::file::write(data, bytes, ec);
    if (ec) write_error = ec;
    return written;
  }
  beast::error_code write_error;
};

}  // namespace

ApiReply ApiClient::download(const std::string& target, const std::filesystem::path& to) const {
  asio::io_context io;
  auto stream = connect(io, host_, port_, timeout_);
  http::request<http::empty_body> req(http::verb::get, target, 11);
  authorise(req, host_ + ":" + port_, token_);
  ApiReply reply;
  const std::filesystem::path tmp = to.string() + ".part";
  // The part file goes on any failure (a full disk, a cut connection, an exception): a file
  // ending mid-line beside the download was left for ever.
  struct RemoveUnlessRenamed {
    const std::filesystem::path& file;
    bool opened = false, renamed = false;
    ~RemoveUnlessRenamed() {
      std::error_code ec;
      if (opened && !renamed) std::filesystem::remove(file, ec);
    }
  } part{tmp};
  http::response_parser<http::basic_file_body<LocalFile>> parser;
  parser.body_limit(boost::none);
  const auto local_failure = [&](const beast::error_code& ec) {
    return std::runtime_error(to.string() + ": cannot write the download of " + target + ": " + ec.message() +
                              " (nothing was kept)");
  };
  try {
    stream.expires_after(timeout_);
    run_op(io, [&](auto handler) { http::async_write(stream, req, handler); });
    beast::flat_buffer buffer;
    beast::error_code ec;
    parser.get().body().open(tmp.c_str(), beast::file_mode::write, ec);
    if (ec) throw local_failure(ec);
    part.opened = true;
    stream.expires_after(timeout_);
    run_op(io, [&](auto handler) { http::async_read(stream, buffer, parser, handler); });
    reply.status = parser.get().result_int();
    reply.content_type = std::string(parser.get()[http::field::content_type]);
    parser.get().body().file().close(ec);
    if (ec) throw local_failure(ec);
  } catch (const boost::system::system_error& e) {
    if (const auto& failed = parser.get().body().file().write_error) throw local_failure(failed);
    throw ApiUnreachable("GET " + target + " at " + host_ + ":" + port_ + ": " + e.code().message());
  }
  // Only a 200 is the file: a 202 (an analysis still running) is a JSON answer like an error.
  if (reply.status == 200) {
    std::filesystem::rename(tmp, to);
    part.renamed = true;
  } else {
    reply.body = hil::read_text_file(tmp);
  }
  return reply;
}

void ApiClient::stream(const std::string& target, const std::function<bool(const std::string&)>& on_message) const {
  asio::io_context io;
  auto tcp_stream = connect(io, host_, port_, timeout_);
  websocket::stream<beast::tcp_stream> ws(std::move(tcp_stream));
  ws.set_option(websocket::stream_base::decorator([this](websocket::request_type& req) {
    req.set(http::field::user_agent, "hilbench-ctl");
    if (!token_.empty()) req.set(http::field::authorization, "Bearer " + token_);
  }));
  websocket::response_type res;
  try {
    beast::get_lowest_layer(ws).expires_after(timeout_);
    run_op(io, [&](auto handler) { ws.async_handshake(res, host_ + ":" + port_, target, handler); });
    // A stream may be quiet for long (no run, between runs): a timeout per message cut an idle
    // `ctl telemetry` after 30 s. The WebSocket's own idle rule instead: a ping to the server at
    // half the timeout without a message, closed only when not even its pong came back.
    beast::get_lowest_layer(ws).expires_never();
    websocket::stream_base::timeout timeouts = websocket::stream_base::timeout::suggested(beast::role_type::client);
    timeouts.idle_timeout = timeout_;
    timeouts.keep_alive_pings = true;
    ws.set_option(timeouts);
    beast::flat_buffer buffer;
    for (;;) {
      run_op(io, [&](auto handler) { ws.async_read(buffer, handler); });
      const std::string message = beast::buffers_to_string(buffer.data());
      buffer.consume(buffer.size());
      if (!on_message(message)) break;
    }
    beast::get_lowest_layer(ws).expires_after(std::chrono::seconds(2));
    try {
      run_op(io, [&](auto handler) { ws.async_close(websocket::close_code::normal, handler); });
    } catch (const boost::system::system_error&) {}
  } catch (const boost::system::system_error& e) {
    if (e.code() == websocket::error::closed) return;
    if (e.code() == websocket::error::upgrade_declined) {
      // Beast keeps the reply it declined: its status and the server's JSON error are the reason,
      // where "the WebSocket handshake was declined" alone hid a 401 or a bad option.
      ApiReply reply{static_cast<int>(res.result_int()), res.body(), std::string(res[http::field::content_type])};
      const std::string what = "WebSocket " + target + " at " + host_ + ":" + port_ + ": the server answered HTTP " +
                               std::to_string(reply.status) + " instead of the upgrade: " + printable(reply.body, 300);
      throw ApiRefused(what, std::move(reply));
    }
    throw ApiUnreachable("WebSocket " + target + " at " + host_ + ":" + port_ + ": " + e.code().message());
  }
}

}  // namespace hil::bench
