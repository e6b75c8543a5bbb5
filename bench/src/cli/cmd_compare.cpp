// hilbench compare --model MODEL.yaml --data FILE.csv|telemetry.mcap [--out DIR] [--quiet]
//                  [--separator S] [--decimal D] [--columns COL=NAME,...]
#include <memory>
#include <string>
#include <vector>

#include "commands.hpp"
#include "csv_format_options.hpp"
#include "hil/analysis/compare.hpp"

namespace hil::bench {

CommandRun define_compare(CLI::App& cmd) {
  struct CompareArgs {
    std::string model_file, out_dir;
    std::vector<std::string> data_files;  // every --data given: more than one is refused
    bool quiet = false;
    CsvFormatArgs format;
  };
  auto args = std::make_shared<CompareArgs>();
  cmd.add_option("--model", args->model_file, "the plant model")->required()->type_name("MODEL.yaml");
  // Every --data kept, not the last (the rule elsewhere): a second file must not be dropped
  // unseen, as one who knows diagnose would expect both compared.
  cmd.add_option("--data", args->data_files, "the measurement (docs/physics.md section 4), or a run's telemetry.mcap")
      ->required()
      ->type_name("FILE.csv")
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  cmd.add_option("--out", args->out_dir, "where the report goes (default out/compare-<FILE>)")
      ->type_name("DIR")
      ->check(path_value());
  add_csv_format_options(cmd, args->format);
  cmd.add_flag("--quiet", args->quiet, "no summary on stdout");
  return [args] {
    analysis::CompareOptions o;
    o.dialect = args->format.dialect();
    o.model_file = args->model_file;
    if (args->data_files.size() > 1) {
      throw UsageError("--data given " + std::to_string(args->data_files.size()) +
                       " times: compare takes one file (hilbench diagnose takes several --data, runs of one rig)");
    }
    o.data_file = args->data_files.front();
    o.out_dir = args->out_dir.empty() ? "out/compare-" + o.data_file.stem().string() : args->out_dir;
    o.quiet = args->quiet;
    analysis::run_compare(o);
    return 0;
  };
}

}  // namespace hil::bench
