// ApiServer: binds the listener, owns the server's state (api_impl.hpp), and answers a raw request
// without a socket for the fuzz target. The parts: api_listener.cpp (accept, connection cap,
// eviction), api_http_session.cpp, api_router.cpp and the resources' routes_*.cpp, the telemetry
// stream beside Foxglove (telemetry_stream.cpp).
#include "api_server.hpp"

#include <algorithm>

#include <boost/beast/http.hpp>
#include <spdlog/spdlog.h>

#include "analyses.hpp"
#include "api_impl.hpp"
#include "api_router.hpp"

namespace hil::bench {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;
using namespace api;

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
    impl_->worker.stop();  // what waits is dropped; what runs is a bounded read or parse
    impl_->worker.join();
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
