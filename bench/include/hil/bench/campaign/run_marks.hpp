// What happened during a run, as its report marks it. A recorded run's events (events.jsonl) are
// read by the report library (hil/report/run_marks.hpp, which compare and diagnose of a run's
// telemetry use too); here, for `hilbench sim` (which has no operator), the campaign's programme.
// Not real-time: allocates.
#pragma once

#include <cstddef>

#include "hil/report/run_marks.hpp"

namespace hil::bench {

struct Campaign;

using report::describe_marks;
using report::mark_label;
using report::marks_from_events;
using report::RunMark;
using report::RunMarks;

// The programmed gap changes of a campaign (at most `max_marks`, the first ones).
RunMarks marks_from_programme(const Campaign& c, std::size_t max_marks = 40);

}  // namespace hil::bench
