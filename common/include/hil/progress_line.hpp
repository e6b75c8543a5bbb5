// The progress line of long offline work (sim, sweep, report, compare), one format and one policy
// for all of them: "LABEL: 45% DETAIL, ETA 12 s".
// - On a terminal the line is redrawn in place at most four times a second and ended at the end.
// - Into a file or a pipe (a CI log, a Slurm task's output) a whole line is written at each new
//   tenth or every 30 s, so a log shows progress without thousands of lines.
// The time left comes from the rate since the line was made. Not real-time safe: it allocates and
// does I/O. Not thread-safe: one caller at a time (callers serialise).
#pragma once

#include <cstdio>
#include <functional>
#include <string>

namespace hil {

class ProgressLine {
 public:
  struct Options {
    std::FILE* out = stderr;
    int tty = -1;                   // 1: terminal policy, 0: log policy, -1: ask isatty(out)
    double delay_s = 0;             // nothing is shown before this: a short job stays silent
    double start_fraction = 0;      // work done before this line was made (a resumed sweep)
    std::function<double()> now_s;  // the clock in seconds (tests); default std::chrono::steady_clock
  };

  explicit ProgressLine(std::string label, Options options);
  explicit ProgressLine(std::string label) : ProgressLine(std::move(label), Options{}) {}
  ~ProgressLine() { end(); }
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;

  // `fraction` of the work is done (0..1). `detail()` gives the text after the percentage, e.g.
  // "(1234 rows)"; it is called only when a line is due, so it may be costly to build.
  template <class Detail>
  void update(double fraction, Detail&& detail) {
    if (due(fraction)) print(fraction, detail());
  }
  void update(double fraction) {
    if (due(fraction)) print(fraction, {});
  }
  // Ends a terminal's line (the last state stays visible); nothing when nothing was shown.
  // Called by the destructor; call it before printing anything else on the stream.
  void end();
  bool shown() const noexcept { return shown_; }

 private:
  bool due(double fraction);
  void print(double fraction, const std::string& detail);

  std::string label_;
  Options o_;
  bool tty_;
  double t0_s_ = 0;  // when the line was made, on o_.now_s
  double last_s_ = -1e300;
  int last_tenth_ = -1;
  std::size_t last_width_ = 0;
  bool shown_ = false, open_ = false;
};

// A duration for people: "42 s", "12 min", "3.5 h"; "?" when not finite.
std::string duration_text(double s);

}  // namespace hil
