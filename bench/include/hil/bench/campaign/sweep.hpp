// Campaign sweeps (`hilbench sweep`): a base campaign and axes, each a YAML path into the campaign,
// its plant or its controller block, with a list, a range or a distribution of values. A point is
// one campaign run through summarise_run, the path of `hilbench sim`; its metrics are one row.
//
// A sweep's folder DIR holds everything the points need (plan.json: the expanded points, the base
// campaign and plant texts), so shards on other machines read only DIR. Finished points are
// whole lines of rows files under DIR/rows/ (one file per writer: local, or one per Slurm shard);
// the outputs (sweep.csv, sweep.json, report.html) are made from them once every point is there.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include "hil/bench/campaign/campaign.hpp"

namespace hil::bench {

enum class AxisKind : std::uint8_t { list, range, uniform, normal };

struct SweepAxis {
  std::string path;  // as written in the sweep file: campaign.gap.initial_deg, plant.effects..., controller.observer
  AxisKind kind = AxisKind::list;
  std::vector<std::string> values;  // list, range: the grid's values as YAML scalars
  double a = 0, b = 0;              // uniform: low, high; normal: mean, sd
  // Another axis path: this axis's value is added to the value there (after the other axes are
  // set), e.g. a gap change as an increment of the swept initial gap. Empty: the value is set.
  std::string relative_to;
  // What the report calls the axis ("initial gap") and its unit ("deg"), as the sweep file gives
  // them (`label:`, `unit:`); empty: from the parameter specs and the key (sweep_words.hpp).
  std::string label, unit;
  bool random() const { return kind == AxisKind::uniform || kind == AxisKind::normal; }
};

struct SweepBound {
  std::string metric;
  std::optional<double> min = std::nullopt, max = std::nullopt;
};

struct SweepMap {
  std::string metric, x, y;
  std::string reduce = "mean";                                  // mean, max or min over the other axes...
  std::vector<std::pair<std::string, std::string>> slice = {};  // ...or these axes held at one value each
  // The map's own threshold (`min:`, `max:` in the map): colours this map and counts its failing
  // points, never the point's pass. Neither: the sweep's threshold of the metric, if any.
  std::optional<double> min = std::nullopt, max = std::nullopt;
};

struct SweepPlan {
  std::string name, description;
  std::string hash;  // of the sweep file and the base campaign and plant texts
  std::string campaign_yaml, plant_yaml;
  std::filesystem::path campaign_dir;  // where the base campaign's relative paths (a reference CSV) resolve
  std::vector<std::string> runs;       // the runs of the base campaign that each point runs
  std::uint64_t seed = 1;
  long samples = 1;
  std::vector<SweepAxis> axes;
  std::vector<SweepBound> thresholds;
  std::vector<SweepMap> maps;
  std::string worst_by;                          // a metric; the worst points are its largest
  std::vector<std::vector<std::string>> points;  // per point, each axis's value as a YAML scalar
  // Every file a point's campaign reads besides its YAML (a csv reference, also one an axis
  // names), with a hash of its contents when the sweep was planned: a sweep resumed, or a shard
  // run, after one of them changed would mix rows made from the old contents with rows from the
  // new (check_input_files).
  struct InputFile {
    std::filesystem::path path;
    std::string hash;  // fnv1a-64 of the contents, 16 hex digits
  };
  std::vector<InputFile> input_files;
  // In this process only, never in plan.json: the campaigns the check loaded, kept so that a
  // fresh sweep's run loads each point once (the second load was about 15 % of a fresh sweep,
  // docs/benchmarks.md), up to kKeptCampaignBytes. Null, or a point's entry null, where none was
  // kept: a resumed plan, a plan read from plan.json, points past the budget.
  std::shared_ptr<const std::vector<std::unique_ptr<const Campaign>>> checked_campaigns;

  long size() const { return static_cast<long>(points.size()); }
  // "<run>.<metric>" for every run: iae_mpa_s, stall_s_per_reversal, stall_vs_none (with a `none`
  // run), touch_changes_per_reversal, gap_error_deg, interlock_trips.
  std::vector<std::string> metric_names() const;
  nlohmann::json to_json() const;
  // Throws std::runtime_error naming `origin` when the plan is not one.
  static SweepPlan from_json(const nlohmann::json& j, const std::string& origin);
};

// Reads and checks SWEEP.yaml, expands its points and checks that every point's campaign loads.
// Throws cfg::Error naming the sweep file, line, column and key (a bad axis path or spec), or
// the point and the loader's message (a value the campaign or plant refuses). More points than
// `max_points` is refused the same way (the fuzz target sets a small limit: each point's check
// loads a campaign). `checked_hash(name)`, when given, is the hash of a plan of that name whose
// points were checked already (the plan.json of a sweep being resumed): a plan with that hash is
// returned without loading its points again.
inline constexpr long kMaxSweepPoints = 1'000'000;
// The most memory a plan's kept campaigns may take (SweepPlan::checked_campaigns), by an
// estimate of their texts and schedules: robustness.yaml's 2160 points take about 12 MB.
inline constexpr std::size_t kKeptCampaignBytes = std::size_t{128} << 20;
struct PlanCheckOptions {
  // A progress line while the points are checked (a load each, about 1 ms: minutes for a large
  // sweep); shown only once the check has taken a second.
  bool progress = false;
  // Set (by a signal handler, say) to stop the check at its next point: plan_sweep throws Cancelled.
  const std::atomic<bool>* cancel = nullptr;
};
SweepPlan plan_sweep(const std::filesystem::path& sweep_file, long max_points = kMaxSweepPoints,
                     const std::function<std::string(const std::string& name)>& checked_hash = {},
                     const PlanCheckOptions& check = {});

// Point p's campaign and plant as YAML, as `hilbench sim` reads them from DIR/points/<p>/ (the
// campaign names its plant `plant.yaml`, beside it).
struct PointYaml {
  std::string campaign, plant;
};
// Makes the points of one plan from its base campaign and plant, parsed once here: a parse was a
// third of each point's load, and a sweep loads every point twice (the plan's check, the run).
// The trees are copied for each point, never changed; one maker per thread (yaml-cpp's nodes are
// not safe to share between threads).
class PointMaker {
 public:
  explicit PointMaker(const SweepPlan& plan);
  PointYaml yaml(long p) const;
  Campaign campaign(long p) const;
  // Runs point p: its metrics in metric_names() order (NaN where one is undefined, e.g. a stall
  // per reversal without reversals). Throws Cancelled (sim.hpp) within about a simulated second
  // once `cancel` is set: the point is abandoned.
  std::vector<double> run(long p, const std::atomic<bool>* cancel = nullptr) const;

 private:
  const SweepPlan& plan_;
  YAML::Node campaign_, plant_;
};
// One point's YAML with a maker of its own (a few points: the report's worst ones, the fuzz target).
PointYaml point_yaml(const SweepPlan& plan, long p);
// Throws std::runtime_error naming the first of plan.input_files whose contents are no longer
// those the sweep was planned with (or that cannot be read), and what to do.
void check_input_files(const SweepPlan& plan, const std::filesystem::path& dir);

// Whether every threshold holds (a NaN metric fails its bound).
bool point_passes(const SweepPlan& plan, const std::vector<double>& metrics);

// The sweep's folder DIR. plan.json holds the plan; rows/<writer>.jsonl the finished points, one
// JSON object a line ({"point": p, "metrics": [...]}, null for NaN).
void write_plan(const std::filesystem::path& dir, const SweepPlan& plan);  // atomic: temp file, then rename
// Throws std::runtime_error naming the file when DIR holds no plan.
SweepPlan read_plan(const std::filesystem::path& dir);
// The finished points of every rows file under DIR/rows/, by point (a point written twice counts
// once: every writer computes the same row). Whole lines that are no row of this plan (damaged,
// or edited by hand) are skipped, their points left missing, and counted into `damaged_lines`.
std::map<long, std::vector<double>> read_rows(const std::filesystem::path& dir, const SweepPlan& plan,
                                              long* damaged_lines = nullptr);

struct SweepRunOptions {
  int jobs = 1;
  bool progress = true;
  long shard = 0, shards = 1;       // only the points p with p % shards == shard
  std::string rows_name = "local";  // the rows file this process appends to: DIR/rows/<rows_name>.jsonl
  // Set (by a signal handler, say) to stop: the points in flight are abandoned (no row), none starts.
  const std::atomic<bool>* cancel = nullptr;
};

struct SweepRunResult {
  long ran = 0;   // points this call ran
  long done = 0;  // points of the sweep finished, by every writer
  long total = 0;
  long missing = 0;        // of this call's share
  long damaged_lines = 0;  // rows-file lines that were no row (read_rows); their points are run again
  bool cancelled = false;
  double wall_s = 0;
};

// Runs the missing points of the share on `jobs` threads, each appended as one whole line of the
// rows file as it finishes. Throws what a point throws (after the points in flight).
SweepRunResult run_sweep(const std::filesystem::path& dir, const SweepPlan& plan, const SweepRunOptions& options);

struct SweepOutputs {
  long missing = 0;         // points without a row: then nothing was written
  long passed = 0;          // points within every threshold
  std::vector<long> worst;  // the worst points by plan.worst_by, worst first (at most 10)
};

// sweep.csv, sweep.json, report.html and, for the worst points, points/<p>/campaign.yaml and
// plant.yaml, once every point has its row.
SweepOutputs write_sweep_outputs(const std::filesystem::path& dir, const SweepPlan& plan);
// The files write_sweep_outputs writes in DIR, all or none.
inline constexpr const char* kSweepOutputs[] = {"sweep.csv", "sweep.json", "report.html"};

// One point's row of sweep.csv (and the header): fixed formatting, so the file is the same bytes
// whoever computed the rows.
std::string sweep_csv_header(const SweepPlan& plan);
std::string sweep_csv_row(const SweepPlan& plan, long p, const std::vector<double>& metrics);

}  // namespace hil::bench
