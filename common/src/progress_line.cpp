#include "hil/progress_line.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>

namespace hil {

namespace {

double steady_now_s() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

// 0..1; an unknown fraction (0/0 of a pipe's size, say) counts as nothing done.
double bounded(double fraction) { return std::isfinite(fraction) ? std::clamp(fraction, 0.0, 1.0) : 0.0; }

// Which tenth of the work `f` (bounded) is in: a log gets a line when it changes.
int tenth_of(double f) { return static_cast<int>(std::floor(f * 10)); }

constexpr double kTerminalEveryS = 0.25;  // a redraw in place: often enough to look alive
constexpr double kLogEveryS = 30;         // a log line between tenths of a slow job

}  // namespace

ProgressLine::ProgressLine(std::string label, Options options)
    : label_(std::move(label)), o_(std::move(options)), tty_(o_.tty >= 0 ? o_.tty == 1 : ::isatty(::fileno(o_.out)) == 1) {
  if (!o_.now_s) o_.now_s = steady_now_s;
  t0_s_ = o_.now_s();
}

bool ProgressLine::due(double fraction) {
  const double now = o_.now_s();
  if (now - t0_s_ < o_.delay_s) return false;
  const double f = bounded(fraction);
  if (tty_) return f >= 1 || now - last_s_ >= kTerminalEveryS;
  return tenth_of(f) > last_tenth_ || now - last_s_ >= kLogEveryS;
}

void ProgressLine::print(double fraction, const std::string& detail) {
  const double now = o_.now_s();
  const double f = bounded(fraction);
  const double elapsed_s = now - t0_s_;
  std::string line = label_ + ": ";
  char pct[16];
  std::snprintf(pct, sizeof pct, "%3.0f%%", 100 * f);
  line += pct;
  if (!detail.empty()) line += " " + detail;
  if (f >= 1) {
    line += ", took " + duration_text(elapsed_s);
  } else if (f > o_.start_fraction && elapsed_s >= 1) {
    // The rate since the line was made, not since the job's start: a resumed job's earlier part
    // took no time here.
    line += ", ETA " + duration_text(elapsed_s * (1 - f) / (f - o_.start_fraction));
  }
  if (tty_) {
    // Blanks over the rest of a longer previous line.
    const std::size_t width = line.size();
    if (width < last_width_) line.append(last_width_ - width, ' ');
    last_width_ = width;
    std::fprintf(o_.out, "\r%s", line.c_str());
    open_ = true;
  } else {
    std::fprintf(o_.out, "%s\n", line.c_str());
  }
  std::fflush(o_.out);
  last_s_ = now;
  last_tenth_ = tenth_of(f);
  shown_ = true;
}

void ProgressLine::end() {
  if (open_) {
    std::fputc('\n', o_.out);
    std::fflush(o_.out);
    open_ = false;
  }
}

std::string duration_text(double s) {
  char buf[32];
  if (!std::isfinite(s)) return "?";
  if (s < 100) {
    std::snprintf(buf, sizeof buf, "%.0f s", s);
  } else if (s < 6000) {
    std::snprintf(buf, sizeof buf, "%.0f min", s / 60);
  } else {
    std::snprintf(buf, sizeof buf, "%.1f h", s / 3600);
  }
  return buf;
}

}  // namespace hil
