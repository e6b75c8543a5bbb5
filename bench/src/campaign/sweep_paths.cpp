#include "sweep_paths.hpp"

#include <charconv>
#include <stdexcept>

namespace hil::bench::sweep_detail {

std::string shortest(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::optional<AxisPath> parse_path(const std::string& text) {
  AxisPath p;
  std::vector<std::string> parts;
  std::string part;
  for (char ch : text) {
    if (ch == '.') {
      parts.push_back(part);
      part.clear();
    } else {
      part += ch;
    }
  }
  parts.push_back(part);
  if (parts.size() < 2) return std::nullopt;
  if (parts[0] == "plant") {
    p.plant = true;
  } else if (parts[0] == "controller") {
    p.steps.push_back({"controller"});
  } else if (parts[0] != "campaign") {
    return std::nullopt;
  }
  for (std::size_t i = 1; i < parts.size(); ++i) {
    std::string s = parts[i];
    const auto bracket = s.find('[');
    const std::string key = s.substr(0, bracket);
    if (key.empty()) return std::nullopt;
    p.steps.push_back({key});
    for (auto at = bracket; at != std::string::npos;) {
      const auto close = s.find(']', at);
      if (close == std::string::npos || close == at + 1) return std::nullopt;
      long index = 0;
      const auto r = std::from_chars(s.data() + at + 1, s.data() + close, index);
      if (r.ec != std::errc() || r.ptr != s.data() + close || index < 0) return std::nullopt;
      p.steps.push_back({"", index});
      at = close + 1 == s.size() ? std::string::npos : close + 1;
      if (at != std::string::npos && s[at] != '[') return std::nullopt;
    }
  }
  return p;
}

YAML::Node walk_checked(YAML::Node root, const AxisPath& path) {
  YAML::Node at = root;
  for (const Step& s : path.steps) {
    if (s.index >= 0) {
      at.reset(at[static_cast<std::size_t>(s.index)]);
    } else {
      at.reset(at[s.key]);
    }
  }
  return at;
}

YAML::Node load_yaml(const std::string& text, const std::string& origin) {
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(origin + ": " + e.what());
  }
}

}  // namespace hil::bench::sweep_detail
