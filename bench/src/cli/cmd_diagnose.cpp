// hilbench diagnose --model MODEL.yaml --data FILE.csv [--data MORE.csv ...] [--out DIR] [--write-model FITTED.yaml]
//                   [--candidates a,b] [--threads N] [--quiet] [--separator S] [--decimal D] [--columns COL=NAME,...]
#include <filesystem>
#include <memory>

#include "cmd_shared.hpp"
#include "commands.hpp"
#include "csv_format_options.hpp"
#include "hil/analysis/diagnose.hpp"
#include "hil/config.hpp"

namespace hil::bench {

CommandRun define_diagnose(CLI::App& cmd) {
  struct DiagnoseArgs {
    std::string model_file, out_dir, write_model, candidates;
    std::vector<std::string> data_files;
    unsigned threads = 0;  // 0: the fitter's default, min(2, hardware)
    bool quiet = false;
    CsvFormatArgs format;
  };
  auto args = std::make_shared<DiagnoseArgs>();
  cmd.add_option("--model", args->model_file, "the plant model")->required()->type_name("MODEL.yaml");
  // One file per --data, every one kept: several runs of one rig are fitted together.
  cmd.add_option("--data", args->data_files,
                 "a measurement (CSV, or a run's telemetry.mcap); several (runs of one rig) are fitted with shared parameters")
      ->required()
      ->type_name("FILE.csv")
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  cmd.add_option("--out", args->out_dir,
                 "where the report goes (default out/diagnose-<first RUN or FILE>-<MODEL>, never another run's)")
      ->type_name("DIR")
      ->check(path_value());
  cmd.add_option("--write-model", args->write_model, "write the model with the effects found")
      ->type_name("FITTED.yaml")
      ->check(path_value());
  cmd.add_option("--candidates", args->candidates, "fit only these candidate effects")->type_name("a,b");
  cmd.add_option("--threads", args->threads, "worker threads of the fitter")->type_name("N")->check(whole_number(1, 64));
  add_csv_format_options(cmd, args->format);
  cmd.add_flag("--quiet", args->quiet, "no summary on stdout");
  return [args] {
    analysis::DiagnoseOptions o;
    o.dialect = args->format.dialect();
    o.model_file = args->model_file;
    // Each --data is a run of the rig: one file given twice (or by another name, ./x or a link)
    // was fitted as two runs, its rows counted twice.
    for (const auto& f : args->data_files) {
      for (const auto& earlier : o.data_files) {
        std::error_code ec;
        if (earlier == f || std::filesystem::equivalent(earlier, f, ec)) {
          throw UsageError("--data " + f + ": is the file of --data " + earlier.string() + " again; give each run's file once");
        }
      }
      o.data_files.emplace_back(f);
    }
    o.out_dir = args->out_dir.empty() ? default_analysis_dir("diagnose", o.data_files, o.model_file, "diagnosis.json")
                                      : std::filesystem::path(args->out_dir);
    o.write_model = args->write_model;
    o.quiet = args->quiet;
    o.settings.candidates = cfg::comma_list(args->candidates);
    // A candidate named twice was fitted and ranked twice.
    if (const std::string* twice = cfg::repeated(o.settings.candidates))
      throw UsageError("--candidates names '" + *twice + "' twice");
    o.settings.threads = args->threads;
    analysis::run_diagnose(o);
    return 0;
  };
}

}  // namespace hil::bench
