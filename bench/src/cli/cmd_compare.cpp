// hilbench compare --model MODEL.yaml --data FILE.csv [--out DIR] [--quiet]
#include <memory>

#include "commands.hpp"
#include "hil/analysis/compare.hpp"

namespace hil::bench {

CommandRun define_compare(CLI::App& cmd) {
  struct CompareArgs {
    std::string model_file, data_file, out_dir;
    bool quiet = false;
  };
  auto args = std::make_shared<CompareArgs>();
  cmd.add_option("--model", args->model_file, "the plant model")->required()->type_name("MODEL.yaml");
  cmd.add_option("--data", args->data_file, "the measurement (docs/physics.md section 4)")->required()->type_name("FILE.csv");
  cmd.add_option("--out", args->out_dir, "where the report goes (default out/compare-<FILE>)")
      ->type_name("DIR")
      ->check(path_value());
  cmd.add_flag("--quiet", args->quiet, "no summary on stdout");
  return [args] {
    analysis::CompareOptions o;
    o.model_file = args->model_file;
    o.data_file = args->data_file;
    o.out_dir = args->out_dir.empty() ? "out/compare-" + o.data_file.stem().string() : args->out_dir;
    o.quiet = args->quiet;
    analysis::run_compare(o);
    return 0;
  };
}

}  // namespace hil::bench
