// Work split over threads whose exceptions reach the caller.
#pragma once

#include <exception>
#include <thread>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_group.h>

namespace strata {

// Runs work(t) for t = 0 .. threads - 1, t = 0 on the calling thread. An exception thrown by any
// of them (std::bad_alloc on a huge scene) is rethrown here once all have finished, instead of
// ending the process from a worker thread.
template <typename Work>
void runOnThreads(unsigned threads, Work work) {
  std::vector<std::exception_ptr> failed(threads);
  auto guarded = [&](unsigned t) {
    try {
      work(t);
    } catch (...) {
      failed[t] = std::current_exception();
    }
  };
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back(guarded, t);
  if (threads > 0) guarded(0);
  for (std::thread& th : pool) th.join();
  for (const std::exception_ptr& e : failed)
    if (e) std::rethrow_exception(e);
}

// The same on oneTBB's pool of worker threads, which lives as long as the process: for work split
// many times a second (the cells order, per view), where starting and joining threads each
// time costs more than the work (on a virtual machine tens of microseconds a thread, and the
// new threads' stacks and caches start cold). Each t is a task of its own, run on whichever
// worker is free (the calling thread takes part); an exception thrown by any of them reaches
// the caller. The context is isolated: called from inside some other TBB algorithm that gets
// cancelled, the tasks still all run (a skipped one would leave its part of the result empty).
template <typename Work>
void runOnPool(unsigned tasks, Work work) {
  if (tasks <= 1) {
    if (tasks == 1) work(0u);
    return;
  }
  tbb::task_group_context context(tbb::task_group_context::isolated);
  tbb::parallel_for(
      tbb::blocked_range<unsigned>(0, tasks, 1),
      [&](const tbb::blocked_range<unsigned>& r) {
        for (unsigned t = r.begin(); t != r.end(); ++t) work(t);
      },
      tbb::simple_partitioner(), context);
}

}  // namespace strata
