#include "cli.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "hil/config.hpp"

namespace hil::bench {

double parse_number(const std::string& text, const std::string& what) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v)) {
    throw UsageError(what + " needs a number, got '" + text + "'");
  }
  return v;
}

double Args::number(const std::string& name, double fallback) const {
  const auto it = options.find(name);
  return it == options.end() ? fallback : parse_number(it->second, "--" + name);
}

Args parse_args(const std::vector<std::string>& argv, const std::vector<std::string>& value_options,
                const std::vector<std::string>& switch_options) {
  Args args;
  std::vector<std::string> known;
  for (const auto& o : value_options) known.push_back("--" + o);
  for (const auto& o : switch_options) known.push_back("--" + o);
  for (std::size_t i = 0; i < argv.size(); ++i) {
    const std::string& a = argv[i];
    if (a.rfind("--", 0) != 0 || a == "--") {
      args.positional.push_back(a);
      continue;
    }
    std::string name = a.substr(2), value;
    const auto eq = name.find('=');
    const bool inline_value = eq != std::string::npos;
    if (inline_value) value = name.substr(eq + 1), name = name.substr(0, eq);
    if (std::find(value_options.begin(), value_options.end(), name) != value_options.end()) {
      if (!inline_value) {
        if (i + 1 >= argv.size()) throw UsageError("option --" + name + " needs a value");
        value = argv[++i];
      }
      args.options[name] = value;  // given again: the last one counts (a wrapper's default, then the user's)
      args.repeated[name].push_back(value);
    } else if (std::find(switch_options.begin(), switch_options.end(), name) != switch_options.end() && !inline_value) {
      args.switches.insert(name);
    } else {
      const std::string hint = cfg::closest("--" + name, known);
      throw UsageError("unknown option --" + name + (hint.empty() ? "" : " (did you mean " + hint + "?)"));
    }
  }
  return args;
}

}  // namespace hil::bench
