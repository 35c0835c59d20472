// The work-splitting helpers of preprocess/core/threads.h: every task runs exactly once, an
// exception thrown by a task reaches the caller, and callers on several threads at once (the
// order made ahead beside a frame's) each get their own tasks run.
#include <atomic>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "preprocess/core/threads.h"

namespace strata {
namespace {

TEST(Threads, EveryTaskRunsOnce) {
  for (unsigned tasks : {0u, 1u, 2u, 7u, 64u}) {
    std::vector<std::atomic<int>> runs(tasks);
    runOnPool(tasks, [&](unsigned t) { runs[t].fetch_add(1); });
    for (unsigned t = 0; t < tasks; ++t) EXPECT_EQ(runs[t].load(), 1) << tasks << " tasks";
    std::vector<std::atomic<int>> spawned(tasks);
    runOnThreads(tasks, [&](unsigned t) { spawned[t].fetch_add(1); });
    for (unsigned t = 0; t < tasks; ++t) EXPECT_EQ(spawned[t].load(), 1) << tasks << " threads";
  }
}

TEST(Threads, AnExceptionReachesTheCaller) {
  auto fail = [](unsigned t) {
    if (t == 3) throw std::runtime_error("task 3");
  };
  EXPECT_THROW(runOnPool(8, fail), std::runtime_error);
  EXPECT_THROW(runOnThreads(8, fail), std::runtime_error);
  // The pool still works afterwards.
  std::atomic<unsigned> sum{0};
  runOnPool(8, [&](unsigned t) { sum += t; });
  EXPECT_EQ(sum.load(), 28u);
}

TEST(Threads, CallersOnSeveralThreadsAtOnce) {
  std::vector<unsigned> sums(4, 0);
  std::vector<std::thread> callers;
  for (unsigned c = 0; c < sums.size(); ++c)
    callers.emplace_back([&sums, c] {
      for (int round = 0; round < 50; ++round) {
        std::vector<unsigned> part(16, 0);
        runOnPool(16, [&](unsigned t) { part[t] = t + c; });
        for (unsigned v : part) sums[c] += v;
      }
    });
  for (std::thread& t : callers) t.join();
  for (unsigned c = 0; c < sums.size(); ++c) EXPECT_EQ(sums[c], 50u * (120u + 16u * c));
}

}  // namespace
}  // namespace strata
