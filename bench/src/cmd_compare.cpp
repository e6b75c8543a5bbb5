// hilbench compare --model MODEL.yaml --data FILE.csv [--out DIR] [--quiet]
#include "cli.hpp"
#include "commands.hpp"
#include "hil/analysis/compare.hpp"

namespace hil::bench {

int cmd_compare(const std::vector<std::string>& argv) {
  const Args args = parse_args(argv, {"model", "data", "out"}, {"quiet"});
  if (!args.positional.empty()) throw UsageError("unexpected argument '" + args.positional[0] + "'");
  if (!args.options.count("model")) throw UsageError("--model MODEL.yaml is required");
  if (!args.options.count("data")) throw UsageError("--data FILE.csv is required");
  analysis::CompareOptions o;
  o.model_file = args.option("model", "");
  o.data_file = args.option("data", "");
  o.out_dir = args.option("out", "out/compare-" + o.data_file.stem().string());
  o.quiet = args.has("quiet");
  analysis::run_compare(o);
  return 0;
}

}  // namespace hil::bench
