#include "api_reply.hpp"

#include <algorithm>
#include <cctype>
#include <sstream>

namespace hil::bench::api {

std::string dump_json(const json& j, int indent) { return j.dump(indent, ' ', false, json::error_handler_t::replace); }

// An answer held in memory (Reply's other members at their defaults).
Reply body_reply(http::status status, std::string body, std::string content_type) {
  Reply r;
  r.status = status;
  r.body = std::move(body);
  r.content_type = std::move(content_type);
  return r;
}
Reply json_reply(http::status status, const json& j) { return body_reply(status, dump_json(j, 2) + "\n", "application/json"); }
Reply error_reply(http::status status, const std::string& error, const std::string& detail, const std::string& field) {
  json j = {{"error", error}};
  if (!detail.empty()) j["detail"] = detail;
  if (!field.empty()) j["field"] = field;  // the request field at fault, for a client to point at
  return json_reply(status, j);
}

Reply error_reply(const ApiError& e) {
  Reply r = error_reply(e.status, e.error, e.detail, e.field);
  r.allow = e.allow;
  return r;
}

namespace {

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

}  // namespace

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

}  // namespace hil::bench::api
