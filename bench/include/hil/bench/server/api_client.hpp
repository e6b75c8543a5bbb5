// A small synchronous client of the bench server's API (hilbench ctl and the end-to-end tests):
// one connection per request, JSON in and out, file downloads, and the WebSocket telemetry stream.
#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

namespace hil::bench {

struct ApiReply {
  int status = 0;
  std::string body;
  std::string content_type;
  nlohmann::json json() const;  // throws std::runtime_error naming the status when the body is not JSON
  bool ok() const { return status >= 200 && status < 300; }
};

// A connection failure or timeout (the server is down or unreachable); HTTP errors are replies.
class ApiUnreachable : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The server answered the request for a WebSocket with an error reply (400 for a bad option, 401
// without the token, 403 from a foreign page) instead of the upgrade: that reply, whose error and
// detail say why.
class ApiRefused : public std::runtime_error {
 public:
  ApiRefused(const std::string& what, ApiReply reply) : std::runtime_error(what), reply_(std::move(reply)) {}
  const ApiReply& reply() const { return reply_; }

 private:
  ApiReply reply_;
};

class ApiClient {
 public:
  // url: "http://127.0.0.1:8470" (or host:port). token: sent as "Authorization: Bearer" when set.
  explicit ApiClient(const std::string& url, std::string token = "",
                     std::chrono::milliseconds timeout = std::chrono::seconds(30));

  ApiReply get(const std::string& target) const;
  ApiReply post(const std::string& target, const nlohmann::json& body) const;
  ApiReply request(const std::string& method, const std::string& target, const std::string& body,
                   const std::string& content_type) const;
  // Streams a file to disk; returns the reply without its body (the body is in `to`). Any answer
  // but 200 leaves `to` alone and comes back with its body.
  ApiReply download(const std::string& target, const std::filesystem::path& to) const;

  // Opens the WebSocket telemetry stream and calls on_message for every message until it returns
  // false, the server closes, or `timeout` passes without a message. An error reply instead of the
  // upgrade is ApiRefused.
  void stream(const std::string& target, const std::function<bool(const std::string&)>& on_message) const;

  const std::string& host() const { return host_; }
  const std::string& port() const { return port_; }

 private:
  std::string host_, port_, token_;
  std::chrono::milliseconds timeout_;
};

}  // namespace hil::bench
