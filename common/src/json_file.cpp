#include "hil/json_file.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "hil/text_file.hpp"

namespace hil {

std::string json_error_position(std::string_view text, std::size_t byte) {
  const std::size_t at = std::min<std::size_t>(byte > 0 ? byte - 1 : 0, text.size());
  std::size_t line = 1, column = 1;
  for (std::size_t i = 0; i < at; ++i) {
    if (text[i] == '\n') {
      ++line;
      column = 1;
    } else {
      ++column;
    }
  }
  return std::to_string(line) + ":" + std::to_string(column);
}

nlohmann::json parse_json_text(std::string_view text, const std::string& origin) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    // what(): "[json.exception.parse_error.101] parse error at line L, column C: REASON"
    std::string reason = e.what();
    const auto c = reason.find("column ");
    const auto colon = c == std::string::npos ? std::string::npos : reason.find(": ", c);
    if (colon != std::string::npos) reason = reason.substr(colon + 2);
    throw std::runtime_error(origin + ":" + json_error_position(text, e.byte) + ": not JSON: " + reason);
  } catch (const nlohmann::json::exception& e) {  // out_of_range: a number like 1e400
    throw std::runtime_error(origin + ": not JSON: " + e.what());
  }
}

nlohmann::json read_json_file(const std::filesystem::path& file) {
  return parse_json_text(read_text_file(file, "a JSON file"), file.string());
}

}  // namespace hil
