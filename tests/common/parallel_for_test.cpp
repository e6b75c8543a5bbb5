// hil::parallel_for, the one parallel loop of sim and sweep: every index runs exactly once on
// any thread count, per-thread state is made once per thread, a false from the body stops the
// handing out, and of several errors the lowest index's is the one thrown (the same on every
// machine).
#include "hil/parallel_for.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

TEST(ParallelFor, EveryIndexRunsOnceWhateverTheThreads) {
  for (unsigned threads : {1u, 2u, 7u, 64u}) {
    std::vector<std::atomic<int>> seen(1000);
    hil::parallel_for(seen.size(), threads, [&](std::size_t i) { seen[i].fetch_add(1); });
    for (std::size_t i = 0; i < seen.size(); ++i) ASSERT_EQ(seen[i].load(), 1) << "index " << i << ", threads " << threads;
  }
  hil::parallel_for(0, 4, [](std::size_t) { ADD_FAILURE() << "no index to run"; });
}

TEST(ParallelFor, StateIsMadeOncePerThreadAndKeptAcrossItsIndices) {
  std::atomic<int> made{0};
  std::atomic<long> sum{0};
  struct Counter {
    long calls = 0;
  };
  hil::parallel_for(
      200, 3,
      [&] {
        made.fetch_add(1);
        return Counter{};
      },
      [&](Counter& c, std::size_t i) {
        ++c.calls;
        sum.fetch_add(static_cast<long>(i));
      });
  EXPECT_GE(made.load(), 1);
  EXPECT_LE(made.load(), 3);
  EXPECT_EQ(sum.load(), 199L * 200 / 2);
}

TEST(ParallelFor, FalseStopsTheHandingOut) {
  // One thread: indices come in order, so exactly 0..5 run.
  std::vector<int> ran;
  hil::parallel_for(100, 1, [&](std::size_t i) {
    ran.push_back(static_cast<int>(i));
    return i < 5;
  });
  EXPECT_EQ(ran, (std::vector<int>{0, 1, 2, 3, 4, 5}));
}

TEST(ParallelFor, TheLowestIndexsErrorIsThrown) {
  // On one thread the error at 3 stops the handing out before 7 starts; on several, 7 may run
  // too, but 3's is thrown either way.
  for (unsigned threads : {1u, 4u}) {
    try {
      hil::parallel_for(50, threads, [](std::size_t i) {
        if (i == 3 || i == 7) throw std::runtime_error("index " + std::to_string(i));
      });
      ADD_FAILURE() << "nothing thrown";
    } catch (const std::runtime_error& e) {
      EXPECT_STREQ(e.what(), "index 3") << threads << " threads";
    }
  }
}

TEST(ParallelFor, WorkerThreadsNeverExceedTheWorkOrTheLimit) {
  EXPECT_EQ(hil::worker_threads(1), 1u);
  EXPECT_EQ(hil::worker_threads(0), 1u);
  EXPECT_LE(hil::worker_threads(1000, 2), 2u);
  EXPECT_GE(hil::worker_threads(1000), 1u);
}

}  // namespace
