// hilbench diagnose --model MODEL.yaml --data FILE.csv [--data MORE.csv ...] [--out DIR] [--write-model FITTED.yaml]
//                   [--candidates a,b] [--threads N] [--quiet]
#include <sstream>

#include "cli.hpp"
#include "commands.hpp"
#include "hil/analysis/diagnose.hpp"

namespace hil::bench {

int cmd_diagnose(const std::vector<std::string>& argv) {
  const Args args = parse_args(argv, {"model", "data", "out", "write-model", "candidates", "threads"}, {"quiet"});
  if (!args.positional.empty()) throw UsageError("unexpected argument '" + args.positional[0] + "'");
  if (!args.options.count("model")) throw UsageError("--model MODEL.yaml is required");
  if (!args.options.count("data")) throw UsageError("--data FILE.csv is required");
  analysis::DiagnoseOptions o;
  o.model_file = args.option("model", "");
  for (const auto& f : args.repeated.at("data")) o.data_files.emplace_back(f);
  o.out_dir = args.option("out", "out/diagnose-" + o.data_files.front().stem().string());
  o.write_model = args.option("write-model", "");
  o.quiet = args.has("quiet");
  std::stringstream names(args.option("candidates", ""));
  for (std::string n; std::getline(names, n, ',');)
    if (!n.empty()) o.settings.candidates.push_back(n);
  if (args.options.count("threads")) {
    const std::string t = args.option("threads", "");
    if (t.empty() || t.find_first_not_of("0123456789") != std::string::npos || std::stoul(t) == 0 || std::stoul(t) > 64)
      throw UsageError("--threads needs a whole number from 1 to 64");
    o.settings.threads = static_cast<unsigned>(std::stoul(t));
  }
  analysis::run_diagnose(o);
  return 0;
}

}  // namespace hil::bench
