// Command-line parsing for the hilbench sub-commands: positional arguments, "--name value"
// options and "--switch" flags. Unknown options fail with a suggestion.
#pragma once

#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace hil::bench {

class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Args {
  std::vector<std::string> positional;
  std::map<std::string, std::string> options;               // each option's value (the last one given)
  std::map<std::string, std::vector<std::string>> repeated;  // every value of each option, in order (diagnose --data)
  std::set<std::string> switches;
  bool has(const std::string& s) const { return switches.count(s) > 0; }
  std::string option(const std::string& name, const std::string& fallback) const {
    const auto it = options.find(name);
    return it == options.end() ? fallback : it->second;
  }
  // Option --name as a number, or `fallback` when absent.
  double number(const std::string& name, double fallback) const;
};

// `text` as a number; a UsageError naming `what` ("--period-ms", "gap") when it is not one.
double parse_number(const std::string& text, const std::string& what);

Args parse_args(const std::vector<std::string>& argv, const std::vector<std::string>& value_options,
                const std::vector<std::string>& switch_options);

}  // namespace hil::bench
