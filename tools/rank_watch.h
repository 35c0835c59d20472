// Liveness of the processes of a distributed render. MPI's collectives wait forever for a
// process that is stopped, hung or gone; here every collective is waited for while the other
// ranks are asked, about once a second, whether they are alive. Each rank answers from a thread
// of its own, so a rank that is only busy (building or rendering its share) stays alive; one
// that has not answered for the timeout is named, and every live rank gives up.
#pragma once

#ifdef STRATA_WITH_MPI

#include <mpi.h>

#include <atomic>
#include <string>
#include <thread>
#include <vector>

namespace strata {

class RankWatch {
 public:
  // Needs MPI initialised with MPI_THREAD_MULTIPLE (without it, waits are plain MPI_Wait).
  // timeout_s: how long a rank may go without answering while another waits for it.
  RankWatch(MPI_Comm world, double timeout_s, bool threads);
  ~RankWatch();
  RankWatch(const RankWatch&) = delete;
  RankWatch& operator=(const RankWatch&) = delete;

  // Completes a nonblocking collective, `what` naming it in the message when a rank goes
  // silent: then every live rank exits with status 1, the lowest of them printing one line
  // that names the silent ranks.
  void wait(MPI_Request& request, const char* what);

  // A last barrier and the answering thread stopped: afterwards no rank waits for another, so
  // none can mistake a rank that has finished for a silent one.
  void finish();

  // This rank failed on its own, outside the steps whose failures the ranks share: every rank is
  // told to exit (status 1), and this one prints `line` ("strata: error: " before it).
  [[noreturn]] void failAlone(const std::string& line);

  int rank() const { return rank_; }
  int size() const { return size_; }

 private:
  void answer();
  void handle(const MPI_Status& status, std::vector<char>& buffer);
  [[noreturn]] void probeAfterTermination();
  [[noreturn]] void giveUp(const std::vector<int>& silent, const char* what, double waited);
  [[noreturn]] void quitAll(const std::string& line, int printer, const std::vector<char>& silent);

  MPI_Comm ask_ = MPI_COMM_NULL;    // to a rank's answering thread: pings, probes, quit
  MPI_Comm reply_ = MPI_COMM_NULL;  // answers to a waiting main thread
  int rank_ = 0, size_ = 1;
  double timeout_s_ = 0.0;
  bool active_ = false;
  MPI_Request pong_ = MPI_REQUEST_NULL;
  int pong_buffer_ = 0;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace strata

#endif
