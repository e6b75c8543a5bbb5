// hilbench compare --model MODEL.yaml --data FILE.csv|telemetry.mcap [--out DIR] [--quiet]
//                  [--separator S] [--decimal D] [--columns COL=NAME,...]
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cmd_shared.hpp"
#include "commands.hpp"
#include "csv_format_options.hpp"
#include "hil/analysis/compare.hpp"
#include "hil/json_file.hpp"

namespace hil::bench {
namespace {

// Whether `dir` may take the result of these inputs: it is new or empty, or its result file
// names the same model and data (compare.json's data_file, diagnosis.json's files).
bool holds_own_or_nothing(const std::filesystem::path& dir, const std::vector<std::filesystem::path>& data_files,
                          const std::filesystem::path& model_file, const std::string& result_file) {
  std::error_code ec;
  if (!std::filesystem::exists(dir, ec)) return true;
  if (!std::filesystem::exists(dir / result_file, ec)) return std::filesystem::is_empty(dir, ec);
  nlohmann::json j;
  try {
    j = read_json_file(dir / result_file);
  } catch (const std::exception&) {
    return false;  // unreadable: someone's, and not overwritten
  }
  const auto same = [&](const nlohmann::json& v, const std::filesystem::path& p) {
    return v.is_string() && (v.get<std::string>() == p.string() || std::filesystem::equivalent(v.get<std::string>(), p, ec));
  };
  if (!same(j.value("model_file", nlohmann::json()), model_file)) return false;
  std::vector<nlohmann::json> recorded;
  if (j.contains("files") && j["files"].is_array())
    for (const auto& f : j["files"])
      recorded.push_back(f.is_object() ? f.value("data_file", nlohmann::json()) : nlohmann::json());
  else
    recorded.push_back(j.value("data_file", nlohmann::json()));
  if (recorded.size() != data_files.size()) return false;
  for (std::size_t i = 0; i < data_files.size(); ++i)
    if (!same(recorded[i], data_files[i])) return false;
  return true;
}

}  // namespace

std::filesystem::path default_analysis_dir(const std::string& kind, const std::vector<std::filesystem::path>& data_files,
                                           const std::filesystem::path& model_file, const std::string& result_file) {
  std::string name = kind + "-" + analysis::measurement_name(data_files.front());
  if (data_files.size() > 1) name += "-and-" + std::to_string(data_files.size() - 1) + "-more";
  name += "-" + analysis::measurement_name(model_file);
  const std::filesystem::path base = std::filesystem::path("out") / name;
  for (int n = 1; n < 10000; ++n) {
    const std::filesystem::path dir = n == 1 ? base : std::filesystem::path(base.string() + "_" + std::to_string(n));
    if (!holds_own_or_nothing(dir, data_files, model_file, result_file)) continue;
    if (n > 1)
      std::fprintf(stderr, "%s holds the %s of other inputs: this one goes to %s\n", base.c_str(), kind.c_str(), dir.c_str());
    return dir;
  }
  throw UsageError(base.string() + "_2 .. _9999 all hold other results: give --out DIR");
}

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
  cmd.add_option("--out", args->out_dir, "where the report goes (default out/compare-<RUN or FILE>-<MODEL>, never another run's)")
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
    o.out_dir = args->out_dir.empty() ? default_analysis_dir("compare", {o.data_file}, o.model_file, "compare.json")
                                      : std::filesystem::path(args->out_dir);
    o.quiet = args->quiet;
    analysis::run_compare(o);
    return 0;
  };
}

}  // namespace hil::bench
