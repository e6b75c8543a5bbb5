// The checks' verdicts while a run goes on (checks.hpp, LiveVerdict): the same windows and the same
// judgement as the run's end (RunChecks::signal_result, which finish() gives for a signal check),
// read from a copy of what add() has seen. Nothing is recomputed from the run's rows: a call costs
// O(checks), so a served run's cost of showing them live grows with how often they are asked for,
// never with the square of its length.
#include <algorithm>
#include <cmath>

#include "hil/bench/campaign/checks.hpp"

namespace hil::bench {

const char* to_string(LiveVerdict v) noexcept {
  switch (v) {
    case LiveVerdict::pending: return "pending";
    case LiveVerdict::passing: return "passing";
    case LiveVerdict::pass: return "pass";
    case LiveVerdict::fail: return "fail";
    case LiveVerdict::skipped: return "skipped";
  }
  return "?";
}

nlohmann::json LiveCheck::to_json() const {
  nlohmann::json j = result.to_json();
  j["verdict"] = to_string(verdict);
  j["decided"] = decided;
  j["at_end"] = at_end;
  return j;
}

// Whether a window of check i may still open after the records of p: its event may come again
// (a reference step or a gap change, programmed or injected by the operator, at any time; a
// reversal while the campaign has more), or its current event's window is still ahead (delay_s,
// the Nth reversal since the event).
bool RunChecks::may_open_again(std::size_t i, const Window& w, const Progress& p) const {
  const CheckSpec& s = *specs_[i];
  if (p.rows == 0) return true;  // the start is still to come
  const std::size_t reversals_left = reversals_s_.size() - std::min(p.next_reversal, reversals_s_.size());
  if (s.after & (kEventReferenceChange | kEventGapChange)) return true;
  if ((s.after & kEventReversal) && reversals_left > 0) return true;
  if (std::isfinite(w.event_t_s)) return p.t_s - w.event_t_s < s.delay_s - 1e-9;
  return s.from_reversal > 0 && w.reversals_since < s.from_reversal &&
         reversals_left >= static_cast<std::size_t>(s.from_reversal - w.reversals_since);
}

std::vector<LiveCheck> RunChecks::live(const Progress& p) const {
  std::vector<LiveCheck> out;
  out.reserve(specs_.size());
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    const CheckSpec& s = *specs_[i];
    LiveCheck c;
    if (!s.signal_check) {
      c.result.check = s.name;
      c.result.run = run_;
      c.result.min = s.min;
      c.result.max = s.max;
      c.result.message = s.quantity() + ": a metric of the whole run, judged at its end";
      c.at_end = true;
      out.push_back(std::move(c));
      continue;
    }
    const Window w = i < p.windows.size() ? p.windows[i] : Window{};
    c.result = signal_result(i, w);
    const double v = c.result.value;
    // The worst value only grows (above max; below min when only a min is set): past the limit
    // now is past it at the end.
    const bool past_for_good = std::isfinite(v) && (s.max ? v > *s.max : (s.min && v < *s.min));
    if (!w.inside && !may_open_again(i, w, p)) {
      c.decided = true;  // no period left for it: the end judges exactly these samples
      c.verdict = c.result.verdict == Verdict::pass   ? LiveVerdict::pass
                  : c.result.verdict == Verdict::fail ? LiveVerdict::fail
                                                      : LiveVerdict::skipped;
    } else if (past_for_good) {
      c.decided = true;
      c.verdict = LiveVerdict::fail;
    } else if (w.closed > 0 && c.result.verdict == Verdict::pass) {
      c.verdict = LiveVerdict::passing;
      c.result.message = "so far " + c.result.message + "; " + std::to_string(w.closed) + " window" + (w.closed == 1 ? "" : "s") +
                         " closed, more may open";
    } else {
      c.verdict = LiveVerdict::pending;
      c.result.message = w.inside       ? "a window is open; so far " + c.result.message
                         : w.closed > 0 ? "between windows; so far " + c.result.message
                                        : s.quantity() + ": its window has not opened yet";
    }
    out.push_back(std::move(c));
  }
  return out;
}

}  // namespace hil::bench
