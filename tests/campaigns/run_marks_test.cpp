// What a run's report marks: events.jsonl lines as the recorder writes them (event_json) become
// labelled marks at their times, a fault a window (its duration, else until it expires, is cleared
// or replaced, else the run's end), loop statistics none; a torn line is skipped and named.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "hil/bench/campaign/run_marks.hpp"
#include "hil/bench/rt/recorder.hpp"
#include "hil/bench/rt/rt_loop.hpp"
#include "hil/units.hpp"
#include "support/temp_file.hpp"

namespace {

using hil::bench::LoopEvent;
using hil::bench::SensorFault;
namespace event = hil::bench::event;

std::string line(double t_s, hil::bench::LoopEventBody body) {
  return hil::bench::event_json(LoopEvent{static_cast<std::int64_t>(t_s * 1000), t_s, body}).dump() + "\n";
}

TEST(RunMarks, EventsBecomeLabelledMarksAndFaultWindows) {
  hil::test::TempDir dir;
  const std::string text = line(2.5, event::Overrun{40.0}) + line(7.3, event::GapChange{hil::units::deg_to_rad(2.5)}) +
                           line(9.0, event::SensorFaultSet{SensorFault::stuck, 1.52e6, 1.0}) +
                           line(10.0, event::FaultExpired{SensorFault::stuck}) + "{\"kind\": \"gap_ch\n" +
                           line(11.0, event::SensorFaultSet{SensorFault::bias, 20e3, 0.0}) + line(12.5, event::FaultsCleared{}) +
                           line(13.0, event::DriveFaultSet{true, 0.0}) +
                           "{\"kind\":\"abort_request\",\"source\":\"operator\"}\n";  // no loop time: not marked
  const auto file = dir.write("events.jsonl", text);
  const auto m = hil::bench::marks_from_events(file, 18.0);
  ASSERT_EQ(m.marks.size(), 6u);
  EXPECT_EQ(m.marks[0].label, "gap 2.5 deg");
  EXPECT_DOUBLE_EQ(m.marks[0].t_s, 7.3);
  EXPECT_TRUE(std::isnan(m.marks[0].end_s));
  EXPECT_EQ(m.marks[1].label, "sensor stuck 1.52 MPa");
  EXPECT_DOUBLE_EQ(m.marks[1].end_s, 10.0);  // its duration, 1 s
  EXPECT_EQ(m.marks[2].label, "sensor stuck fault expired");
  EXPECT_EQ(m.marks[3].label, "sensor bias 20 kPa");
  EXPECT_DOUBLE_EQ(m.marks[3].end_s, 12.5);  // until cleared
  EXPECT_EQ(m.marks[4].label, "faults cleared");
  EXPECT_EQ(m.marks[5].label, "drive ignores commands");
  EXPECT_DOUBLE_EQ(m.marks[5].end_s, 18.0);  // still on at the run's end
  EXPECT_EQ(m.unreadable, file.string() + ":5: not a JSON object");
  EXPECT_EQ(hil::bench::describe_marks(m.marks, 2), "gap 2.5 deg at 7.300 s; sensor stuck 1.52 MPa 9.000-10.000 s; and 4 more");
}

TEST(RunMarks, AMissingFileHasNoMarks) {
  hil::test::TempDir dir;
  const auto m = hil::bench::marks_from_events(dir.path() / "events.jsonl", 1.0);
  EXPECT_TRUE(m.marks.empty());
  EXPECT_TRUE(m.unreadable.empty());
}

}  // namespace
