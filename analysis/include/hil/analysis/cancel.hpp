// A cooperative stop for the long analyses (compare, diagnose): the caller owns a flag and sets it
// from another thread (a server shutting down). The analysis looks at it between units of work (a
// chunk of rows in compare; a candidate's fit, a level of a grid search, a round in diagnose) and
// throws Cancelled, having written nothing: a stop costs at most one unit, never the whole search.
#pragma once

#include <atomic>
#include <stdexcept>

namespace hil::analysis {

struct Cancelled : std::runtime_error {
  using std::runtime_error::runtime_error;
};

inline void throw_if_cancelled(const std::atomic<bool>* cancel) {
  if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) throw Cancelled("the analysis was cancelled");
}

}  // namespace hil::analysis
