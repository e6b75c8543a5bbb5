// A table of named kinds that register themselves, each from a static initialiser in its own .cpp
// (the plant's effects, the bench's rig kinds). One table per Info type, built on first use
// inside a function: registrations run from other translation units' static initialisers, whose
// order against the table's own would otherwise be unspecified.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace hil {

template <class Info>
class Registry {
 public:
  // Adds a kind; the first registration of a name wins. Returns the kept entry and its name,
  // which lives as long as the program (a string_view into it stays valid).
  static std::pair<const std::string&, Info&> add(std::string_view name, const Info& info) {
    auto& [key, value] = *table().emplace(std::string(name), info).first;
    return {key, value};
  }
  static const Info* find(std::string_view name) {
    const auto it = table().find(name);
    return it == table().end() ? nullptr : &it->second;
  }
  // Every name, sorted.
  static std::vector<std::string> names() {
    std::vector<std::string> out;
    for (const auto& entry : table()) out.push_back(entry.first);
    return out;
  }

 private:
  static std::map<std::string, Info, std::less<>>& table() {
    static std::map<std::string, Info, std::less<>> entries;
    return entries;
  }
};

}  // namespace hil
