// Fuzz target "sweep": the bytes as a sweep file (SWEEP.yaml of `hilbench sweep`), planned by
// hil::bench::plan_sweep: the keys, the axes (YAML paths into the campaign and its plant, lists,
// ranges, distributions, relative_to), thresholds, maps and slices, then every point's campaign
// through the campaign loader. The sweep file sits in a folder where `campaigns/` and `plant/`
// are the shipped configs, so "campaign: campaigns/paper_adaptive.yaml" loads a real base.
// A plan is then written to JSON and read back (plan.json), which must give the same plan; and
// the bytes are read as a plan.json themselves (a damaged output folder), and as a rows file of a
// fixed three-point plan (rows/<writer>.jsonl, which a killed writer or a hand edit may damage).
// Clear errors: hil::cfg::Error from planning (file:line:column: key: what); std::runtime_error
// naming the file from reading a plan.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

#include "fuzz_support.hpp"
#include "hil/bench/campaign/sweep.hpp"
#include "hil/config.hpp"

namespace {

// Each point's check loads a campaign (about a millisecond): a small grid keeps every input fast.
constexpr long kFuzzMaxPoints = 32;

const std::filesystem::path& sweep_file() {
  static hil::fuzz::InputFile file("sweep.yaml");
  static const bool linked = [] {
    std::error_code ec;
    for (const char* sub : {"campaigns", "plant"}) {
      std::filesystem::create_directory_symlink(std::filesystem::path(HIL_SOURCE_DIR "/configs") / sub, file.dir() / sub, ec);
      if (ec) {
        std::fprintf(stderr, "fuzz: cannot link %s: %s\n", sub, ec.message().c_str());
        std::abort();
      }
    }
    return true;
  }();
  (void)linked;
  return file.path();
}

// The fixed plan the bytes are read against as a rows file, and its folder.
struct RowsFolder {
  hil::bench::SweepPlan plan;
  std::filesystem::path dir;
};
const RowsFolder& rows_folder() {
  static const RowsFolder folder = [] {
    (void)sweep_file();  // campaigns/ and plant/ linked beside it, where the plan file goes too
    static hil::fuzz::InputFile plan_file("rows_plan.yaml");
    const std::string text =
        "name: rows\ncampaign: campaigns/paper_adaptive.yaml\nruns: [none]\naxes:\n  - path: campaign.seed\n    values: [1, 2, "
        "3]\n";
    plan_file.write(reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
    RowsFolder r{hil::bench::plan_sweep(plan_file.path(), kFuzzMaxPoints), plan_file.dir() / "rows_sweep"};
    std::filesystem::create_directories(r.dir / "rows");
    return r;
  }();
  return folder;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto& file = sweep_file();
  {
    std::FILE* f = std::fopen(file.c_str(), "wb");
    if (f == nullptr || std::fwrite(data, 1, size, f) != size || std::fclose(f) != 0) std::abort();
  }
  hil::fuzz::expect_clear_errors<hil::cfg::Error>("bench::plan_sweep", [&] {
    const hil::bench::SweepPlan plan = hil::bench::plan_sweep(file, kFuzzMaxPoints);
    const nlohmann::json j = plan.to_json();
    const hil::bench::SweepPlan back = hil::bench::SweepPlan::from_json(j, "plan.json");
    if (back.to_json() != j) {
      std::fprintf(stderr, "\nFINDING: plan.json does not read back as the same plan\n");
      std::abort();
    }
    if (plan.size() > 0) (void)hil::bench::point_yaml(plan, plan.size() - 1);
  });
  // As a rows file: whatever the bytes, only rows of the plan come back, each of the plan's width.
  {
    const RowsFolder& folder = rows_folder();
    static hil::fuzz::InputFile rows_file("rows_sweep/rows/local.jsonl");
    rows_file.write(data, size);
    long damaged = -1;
    const auto rows = hil::bench::read_rows(folder.dir, folder.plan, &damaged);
    const std::size_t width = folder.plan.metric_names().size();
    bool bad = damaged < 0 || static_cast<long>(rows.size()) > folder.plan.size();
    for (const auto& [p, metrics] : rows) bad = bad || p < 0 || p >= folder.plan.size() || metrics.size() != width;
    if (bad) {
      std::fprintf(stderr, "\nFINDING: read_rows gave %zu rows (damaged %ld) outside the plan\n", rows.size(), damaged);
      std::abort();
    }
  }
  const nlohmann::json j = nlohmann::json::parse(data, data + size, nullptr, /*allow_exceptions=*/false);
  if (!j.is_discarded()) {
    hil::fuzz::expect_clear_errors<std::runtime_error>("bench::SweepPlan::from_json",
                                                       [&] { (void)hil::bench::SweepPlan::from_json(j, "plan.json"); });
  }
  return 0;
}
