// What happened during a run, as a report marks it: each event a labelled line at its time, a
// fault a shaded window (start..end), and a sentence for the report's header ("gap 2.5 deg at
// 7.300 s"). From a recorded run's events.jsonl: the run report (`hilbench report`, a served
// run's), and compare/diagnose of a run's telemetry (events.jsonl beside it). Here, in the report
// library, because analysis/ may not depend on bench/; the campaign's programmed marks
// (`hilbench sim`, no operator) are bench's (hil/bench/campaign/run_marks.hpp). Not real-time:
// allocates.
#pragma once

#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

namespace hil::report {

struct Figure;

struct RunMark {
  double t_s = 0;
  double end_s = std::numeric_limits<double>::quiet_NaN();  // a fault's window end; NaN: an instant
  std::string label;                                        // "gap 2.5 deg", "sensor stuck 1.52 MPa"
  std::string kind;                                         // the event's kind in events.jsonl
  std::string source;                                       // who made it: operator, safety, loop
  double value = std::numeric_limits<double>::quiet_NaN();  // a gap change's gap [deg]; NaN otherwise
};

struct RunMarks {
  std::vector<RunMark> marks;  // in time order
  // Lines of events.jsonl that could not be read, first one named (file:line: why); empty: none.
  std::string unreadable;
};

// The marked events of a recorded run (operator actions, injections, faults, trips, the safe state;
// loop statistics such as overruns are not marked). A fault without a duration lasts until it
// expires, is cleared, replaced, or the run ends at end_s. A missing file gives no marks; a line
// that is not a JSON object with a finite t_s is skipped and counted in `unreadable`.
RunMarks marks_from_events(const std::filesystem::path& events_jsonl, double end_s);

// The label of an event of events.jsonl worth marking ("gap 2.5 deg", "sensor stuck 1.52 MPa",
// "trip: overpressure"); empty for what is not marked (loop statistics, run bookkeeping). The one
// wording of the reports and of the console's live plots (the event feed adds it as "mark").
std::string mark_label(const nlohmann::json& event);

// "gap 2.5 deg at 7.300 s; sensor stuck 1.52 MPa 9.000-10.000 s" (at most max_items, then "and N more").
std::string describe_marks(const std::vector<RunMark>& marks, std::size_t max_items = 12);

// The marks on a time figure: each a labelled line (`prefix` before its label, e.g. the run's
// name where runs share a plot), and with `with_bands` each fault's window shaded, in the one
// palette's event and fault-window colours.
void mark_figure(Figure& figure, const RunMarks& marks, bool with_bands, const std::string& prefix = "");

}  // namespace hil::report
