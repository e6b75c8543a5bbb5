// The sweep's folder and its points on threads: plan.json, the rows files, the resumable run.

#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>

#include "hil/bench/campaign/sim.hpp"
#include "hil/bench/campaign/sweep.hpp"
#include "hil/file_lock.hpp"
#include "hil/line_file.hpp"
#include "hil/parallel_for.hpp"
#include "hil/progress_line.hpp"
#include "hil/json_file.hpp"
#include "hil/text_file.hpp"

namespace hil::bench {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

std::string row_line(long p, const std::vector<double>& metrics) {
  json m = json::array();
  for (double v : metrics) {
    if (std::isfinite(v)) {
      m.push_back(v);
    } else {
      m.push_back(nullptr);
    }
  }
  return json{{"point", p}, {"metrics", m}}.dump() + "\n";
}

}  // namespace

void write_plan(const std::filesystem::path& dir, const SweepPlan& plan) {
  std::filesystem::create_directories(dir);
  replace_file(dir / "plan.json", plan.to_json().dump(1) + "\n");
}

SweepPlan read_plan(const std::filesystem::path& dir) {
  const auto file = dir / "plan.json";
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec))
    throw std::runtime_error(file.string() + ": no sweep plan here (plan a sweep with hilbench sweep SWEEP.yaml --out DIR)");
  return SweepPlan::from_json(read_json_file(file), file.string());
}

std::map<long, std::vector<double>> read_rows(const std::filesystem::path& dir, const SweepPlan& plan, long* damaged_lines) {
  std::map<long, std::vector<double>> rows;
  long damaged = 0;
  const auto rows_dir = dir / "rows";
  if (!std::filesystem::is_directory(rows_dir)) return rows;
  const std::size_t width = plan.metric_names().size();
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(rows_dir)) {
    if (e.is_regular_file() && e.path().extension() == ".jsonl") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());  // the same first row of a point, whatever the directory order
  for (const auto& file : files) {
    const std::string all = hil::read_text_file(file);
    // Only whole lines: a writer that is still at it (or died in a write) may have a partial last one.
    std::size_t start = 0;
    for (std::size_t end = all.find('\n'); end != std::string::npos; start = end + 1, end = all.find('\n', start)) {
      const json j = json::parse(all.begin() + static_cast<long>(start), all.begin() + static_cast<long>(end), nullptr, false);
      const bool row = !j.is_discarded() && j.is_object() && j.contains("point") && j.contains("metrics") &&
                       j["point"].is_number_integer() && j["metrics"].is_array() && j["metrics"].size() == width &&
                       j["point"].get<long>() >= 0 && j["point"].get<long>() < plan.size();
      if (!row) {
        ++damaged;
        continue;
      }
      const long p = j["point"].get<long>();
      if (rows.count(p)) continue;
      std::vector<double> m;
      for (const auto& v : j["metrics"]) m.push_back(v.is_number() ? v.get<double>() : std::numeric_limits<double>::quiet_NaN());
      rows.emplace(p, std::move(m));
    }
  }
  if (damaged_lines != nullptr) *damaged_lines = damaged;
  return rows;
}

namespace {

// One writer per rows file: a second `hilbench sweep` on the same --out (or the same shard twice)
// would run the same points and splice its lines into the first one's. The lock is taken before
// the rows are read, so the second learns of it before it plans any work; it goes with the process.
FileLock lock_rows(const std::filesystem::path& rows_file) {
  std::filesystem::create_directories(rows_file.parent_path());
  std::string name = ".";  // appended, not "." + ...: GCC 12 warns falsely (-Wrestrict) on that
  name += rows_file.filename().string();
  name += ".lock";
  try {
    return FileLock(rows_file.parent_path() / name);
  } catch (const FileLock::Busy&) {
    throw std::runtime_error("another hilbench sweep is writing " + rows_file.string() +
                             " (the same --out and shard): wait for it to end, or stop it; then run this again");
  }
}

}  // namespace

SweepRunResult run_sweep(const std::filesystem::path& dir, const SweepPlan& plan, const SweepRunOptions& options) {
  const auto t0 = Clock::now();
  SweepRunResult result;
  result.total = plan.size();
  const auto rows_file = dir / "rows" / (options.rows_name + ".jsonl");
  const FileLock lock = lock_rows(rows_file);
  const auto done = read_rows(dir, plan, &result.damaged_lines);
  std::vector<long> todo;
  long shard_done = 0;  // this shard's points done before: where its progress starts
  for (long p = options.shard; p < plan.size(); p += options.shards) {
    if (!done.count(p))
      todo.push_back(p);
    else
      ++shard_done;
  }
  result.done = static_cast<long>(done.size());
  result.missing = static_cast<long>(todo.size());
  if (todo.empty()) return result;
  check_input_files(plan, dir);  // before a row is made from a file that is no longer the planned one

  if (std::filesystem::exists(rows_file)) trim_to_whole_lines(rows_file);
  LineFile rows(rows_file, /*append=*/true);

  std::mutex mutex;  // guards rows, the counters below and the progress line
  long ran = 0;
  const long shard_total = shard_done + static_cast<long>(todo.size());
  std::optional<ProgressLine> progress_line;  // not `line`: the workers' row lines are named so
  if (options.progress) {
    ProgressLine::Options po;
    po.start_fraction = static_cast<double>(shard_done) / static_cast<double>(shard_total);
    // A shard as --shard names it (and its log file and rows): 0-based.
    progress_line.emplace(options.shards > 1 ? "sweep " + plan.name + " shard " + std::to_string(options.shard) + "/" +
                                                   std::to_string(options.shards)
                                             : "sweep " + plan.name,
                          po);
  }
  const auto t_run = Clock::now();
  auto progress = [&] {
    if (!progress_line) return;
    progress_line->update(static_cast<double>(shard_done + ran) / static_cast<double>(shard_total), [&] {
      const double elapsed_s = std::chrono::duration<double>(Clock::now() - t_run).count();
      char detail[96];
      std::snprintf(detail, sizeof detail, "(%ld/%ld points, %.1f points/s)", shard_done + ran, shard_total,
                    elapsed_s > 0 ? ran / elapsed_s : 0.0);
      return std::string(detail);
    });
  };
  // The points on `jobs` threads (hil/parallel_for.hpp), a PointMaker per thread made at its first
  // point (in the body: a plan whose base does not parse is this sweep's error, thrown once every
  // thread has ended); a cancel stops the handing out, the point in flight is abandoned.
  const auto jobs = static_cast<unsigned>(std::max(1, std::min<int>(options.jobs, static_cast<int>(todo.size()))));
  try {
    hil::parallel_for(
        todo.size(), jobs, [] { return std::optional<PointMaker>(); },
        [&](std::optional<PointMaker>& maker, std::size_t i) {
          if (options.cancel != nullptr && options.cancel->load()) return false;
          try {
            if (!maker) maker.emplace(plan);
            const std::string line = row_line(todo[i], maker->run(todo[i], options.cancel));
            std::lock_guard lock(mutex);
            rows.append(line);
            ++ran;
            progress();
          } catch (const Cancelled&) {
            return false;  // its row never written
          }
          return true;
        });
  } catch (...) {
    if (progress_line) progress_line->end();
    throw;
  }
  if (progress_line) progress_line->end();
  result.ran = ran;
  result.done += ran;
  result.missing -= ran;
  result.cancelled = result.missing > 0;
  result.wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return result;
}

}  // namespace hil::bench
