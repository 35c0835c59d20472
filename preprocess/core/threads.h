// Work split over threads whose exceptions reach the caller.
#pragma once

#include <exception>
#include <thread>
#include <vector>

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

}  // namespace strata
