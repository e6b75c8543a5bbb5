// The progress line of long work (sim, sweep, report, compare): what a log and a terminal get, on
// a clock the test moves, so nothing here depends on how busy the machine is.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "hil/progress_line.hpp"

namespace {

// A stream to write into and read back, and a clock the test sets.
struct Sink {
  std::FILE* file = std::tmpfile();
  double now_s = 100;
  ~Sink() { std::fclose(file); }
  hil::ProgressLine::Options options(int tty) {
    hil::ProgressLine::Options o;
    o.out = file;
    o.tty = tty;
    o.now_s = [this] { return now_s; };
    return o;
  }
  std::string text() {
    std::fflush(file);
    std::string s(static_cast<std::size_t>(std::ftell(file)), '\0');
    std::rewind(file);
    s.resize(std::fread(s.data(), 1, s.size(), file));
    std::fseek(file, 0, SEEK_END);
    return s;
  }
  std::vector<std::string> lines() {
    std::vector<std::string> out;
    const std::string s = text();
    for (std::size_t a = 0, b; (b = s.find('\n', a)) != std::string::npos; a = b + 1) out.push_back(s.substr(a, b - a));
    return out;
  }
};

TEST(ProgressLine, ALogGetsOneWholeLinePerTenthWithTheTimeLeftAndTheTimeTaken) {
  Sink sink;
  {
    hil::ProgressLine line("sim x", sink.options(0));
    for (int i = 0; i <= 100; ++i) {  // 1 % every 0.1 s: 10 s in all
      line.update(i / 100.0, [&] {
        char detail[32];
        std::snprintf(detail, sizeof detail, "(%d rows)", i);
        return std::string(detail);
      });
      sink.now_s += 0.1;
    }
  }
  const auto lines = sink.lines();
  ASSERT_EQ(lines.size(), 11u) << sink.text();
  EXPECT_EQ(lines[0], "sim x:   0% (0 rows)");  // no rate yet: no estimate
  EXPECT_EQ(lines[5], "sim x:  50% (50 rows), ETA 5 s");
  EXPECT_EQ(lines[10], "sim x: 100% (100 rows), took 10 s");
  EXPECT_EQ(sink.text().back(), '\n');
  EXPECT_EQ(sink.text().find('\r'), std::string::npos);
}

TEST(ProgressLine, ASlowJobStillWritesALogLineEveryHalfMinute) {
  Sink sink;
  hil::ProgressLine line("sweep s", sink.options(0));
  for (int i = 0; i <= 12; ++i) {  // 0.1 % every 10 s: no new tenth in two minutes
    line.update(i / 1000.0);
    sink.now_s += 10;
  }
  // At 0, 30, 60, 90 and 120 s.
  const auto lines = sink.lines();
  ASSERT_EQ(lines.size(), 5u) << sink.text();
  EXPECT_EQ(lines[4], "sweep s:   1%, ETA 2.7 h");  // 1.2 % in 120 s: 9 880 s left
}

TEST(ProgressLine, ATerminalIsRedrawnInPlaceAtMostFourTimesASecondAndEndedOnce) {
  Sink sink;
  hil::ProgressLine line("report", sink.options(1));
  line.update(0.0, [] { return std::string("of the telemetry, a longer text"); });
  for (int i = 1; i <= 9; ++i) {  // nine updates 0.1 s apart: redraws at 0.3, 0.6 and 0.9 s
    sink.now_s += 0.1;
    line.update(i / 10.0, [] { return std::string("read"); });
  }
  const std::string drawn = sink.text();
  EXPECT_EQ(drawn.find('\n'), std::string::npos) << "a terminal's line ends only at the end";
  std::vector<std::string> frames;
  for (std::size_t a = drawn.find('\r'), b; a != std::string::npos; a = b) {
    b = drawn.find('\r', a + 1);
    frames.push_back(drawn.substr(a + 1, b == std::string::npos ? std::string::npos : b - a - 1));
  }
  ASSERT_EQ(frames.size(), 4u) << drawn;
  EXPECT_EQ(frames[0], "report:   0% of the telemetry, a longer text");
  // A shorter line blanks the rest of the longer one it replaces.
  EXPECT_EQ(frames[1].size(), frames[0].size()) << "'" << frames[1] << "'";
  EXPECT_EQ(frames[1].rfind("report:  30% read", 0), 0u) << frames[1];
  line.update(1.0, [] { return std::string("read"); });  // the end is always drawn
  line.end();
  line.end();
  const std::string all = sink.text();
  EXPECT_EQ(all.substr(all.rfind('\r') + 1), "report: 100% read, took 1 s\n");
}

TEST(ProgressLine, NothingIsShownBeforeTheDelayAndTheDetailIsBuiltOnlyForAShownLine) {
  Sink sink;
  int built = 0;
  {
    hil::ProgressLine::Options o = sink.options(1);
    o.delay_s = 1;
    hil::ProgressLine line("compare", o);
    for (int i = 0; i < 9; ++i) {
      sink.now_s += 0.1;
      line.update(i / 10.0, [&] { return std::to_string(++built); });
    }
    EXPECT_FALSE(line.shown());
  }
  EXPECT_EQ(built, 0);
  EXPECT_EQ(sink.text(), "") << "a short job leaves nothing, not even an empty line";
}

TEST(ProgressLine, AResumedJobsTimeLeftComesFromTheWorkDoneSinceItResumed) {
  Sink sink;
  hil::ProgressLine::Options o = sink.options(0);
  o.start_fraction = 0.5;  // half was done by an earlier run
  hil::ProgressLine line("sweep r", o);
  sink.now_s += 10;
  line.update(0.75);  // a quarter in 10 s: a quarter left, 10 s
  EXPECT_EQ(sink.lines().at(0), "sweep r:  75%, ETA 10 s");
}

TEST(ProgressLine, AnUnknownFractionCountsAsNothingDoneNeverAsGarbage) {
  Sink sink;
  hil::ProgressLine line("compare", sink.options(0));
  line.update(0.0 / 0.0);  // a pipe's progress: rows read of an unknown size
  line.update(-0.5);
  sink.now_s += 2;
  line.update(7.0);  // past the end: shown as the end
  const auto lines = sink.lines();
  ASSERT_EQ(lines.size(), 2u) << sink.text();
  EXPECT_EQ(lines[0], "compare:   0%");
  EXPECT_EQ(lines[1], "compare: 100%, took 2 s");
}

TEST(ProgressLine, DurationsReadAsPeopleSayThem) {
  EXPECT_EQ(hil::duration_text(42.4), "42 s");
  EXPECT_EQ(hil::duration_text(720), "12 min");
  EXPECT_EQ(hil::duration_text(12600), "3.5 h");
  EXPECT_EQ(hil::duration_text(1.0 / 0.0), "?");
}

}  // namespace
