#include "tools/rank_watch.h"

#ifdef STRATA_WITH_MPI

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <cstring>

#include <unistd.h>

#include "preprocess/core/files.h"

namespace strata {

namespace {

enum Tag : int { kPing = 1, kPong = 2, kProbe = 3, kProbeAnswer = 4, kQuit = 5 };

const int kToken = 0;
constexpr int kMessageBytes = 1024;

// Set by SIGTERM, which the MPI launcher sends every process when one of them has died: the
// answering thread then finds out which rank no longer answers before the process ends.
std::atomic<bool> terminated{false};
struct sigaction previous_term {};
bool term_installed = false;
void onTerminate(int) { terminated.store(true); }

// Only one path of a process (its main thread giving up, or its thread told to) exits.
std::atomic<bool> quitting{false};

void sendToken(int to, int tag, MPI_Comm comm) {
  MPI_Request r;  // as bytes: the receives take any message as bytes
  MPI_Isend(&kToken, int(sizeof(kToken)), MPI_BYTE, to, tag, comm, &r);
  MPI_Request_free(&r);
}

// "rank 2", "ranks 2 and 5", "ranks 1, 2 and 5".
std::string rankList(const std::vector<int>& ranks) {
  std::string s = ranks.size() == 1 ? "rank " : "ranks ";
  for (size_t i = 0; i < ranks.size(); ++i) {
    if (i > 0) s += i + 1 == ranks.size() ? " and " : ", ";
    s += std::to_string(ranks[i]);
  }
  return s;
}

[[noreturn]] void printAndExit(const char* line, bool print, int status) {
  if (print) {
    std::fprintf(stderr, "strata: error: %s\n", line);
    std::fflush(stderr);
  }
  std::fflush(stdout);
  // Not exit(): MPI_Finalize would wait for the silent rank. The files being written go first.
  removeTemporaryFilesNow();
  _exit(status);
}

// Spins briefly (collectives of a frame finish within milliseconds), then sleeps.
void idleBriefly(int& idle) {
  if (++idle < 2000)
    sched_yield();
  else
    usleep(idle < 20000 ? 100 : 1000);
}

}  // namespace

RankWatch::RankWatch(MPI_Comm world, double timeout_s, bool threads) : timeout_s_(timeout_s) {
  MPI_Comm_rank(world, &rank_);
  MPI_Comm_size(world, &size_);
  active_ = threads && timeout_s > 0.0 && size_ > 1;
  if (!active_) return;
  MPI_Comm_dup(world, &ask_);
  MPI_Comm_dup(world, &reply_);
  MPI_Irecv(&pong_buffer_, int(sizeof(pong_buffer_)), MPI_BYTE, MPI_ANY_SOURCE, kPong, reply_,
            &pong_);
  terminated.store(false);
  struct sigaction old {};
  if (::sigaction(SIGTERM, nullptr, &old) == 0 && old.sa_handler != SIG_IGN) {
    struct sigaction action {};
    action.sa_handler = onTerminate;
    action.sa_flags = SA_RESTART;  // the main thread's reads and writes go on meanwhile
    sigemptyset(&action.sa_mask);
    term_installed = ::sigaction(SIGTERM, &action, &previous_term) == 0;
  }
  thread_ = std::thread([this] { answer(); });
}

RankWatch::~RankWatch() { finish(); }

void RankWatch::finish() {
  if (!active_) return;
  MPI_Request barrier;
  MPI_Ibarrier(ask_, &barrier);
  wait(barrier, "the last barrier");
  stop_.store(true);
  thread_.join();
  MPI_Cancel(&pong_);
  MPI_Wait(&pong_, MPI_STATUS_IGNORE);
  active_ = false;
  if (term_installed) {
    ::sigaction(SIGTERM, &previous_term, nullptr);
    term_installed = false;
    if (terminated.load()) std::raise(SIGTERM);
  }
}

void RankWatch::answer() {
  std::vector<char> buffer(kMessageBytes);
  MPI_Request request;
  const auto post = [&] {
    MPI_Irecv(buffer.data(), kMessageBytes, MPI_BYTE, MPI_ANY_SOURCE, MPI_ANY_TAG, ask_, &request);
  };
  post();
  while (!stop_.load()) {
    int got = 0;
    MPI_Status status;
    MPI_Test(&request, &got, &status);
    if (!got) {
      if (terminated.load()) {
        MPI_Cancel(&request);
        MPI_Wait(&request, MPI_STATUS_IGNORE);
        probeAfterTermination();
      }
      usleep(1000);
      continue;
    }
    handle(status, buffer);
    post();
  }
  MPI_Cancel(&request);
  MPI_Wait(&request, MPI_STATUS_IGNORE);
}

void RankWatch::handle(const MPI_Status& status, std::vector<char>& buffer) {
  const int from = status.MPI_SOURCE;
  if (status.MPI_TAG == kPing) sendToken(from, kPong, reply_);
  if (status.MPI_TAG == kProbe) sendToken(from, kProbeAnswer, ask_);
  if (status.MPI_TAG == kQuit && !quitting.exchange(true)) {
    int length = 0, printer = 0;
    MPI_Get_count(&status, MPI_BYTE, &length);
    std::memcpy(&printer, buffer.data(), sizeof(int));
    buffer[size_t(std::clamp(length, 4, kMessageBytes - 1))] = '\0';
    printAndExit(buffer.data() + sizeof(int), printer == rank_, 1);
  }
}

void RankWatch::probeAfterTermination() {
  // Every process of the job has been sent SIGTERM; for a moment the live ones still answer
  // one another's probes, and the lowest of them names the ranks that do not.
  std::vector<char> answered(size_t(size_), 0);
  answered[size_t(rank_)] = 1;
  for (int r = 0; r < size_; ++r)
    if (r != rank_) sendToken(r, kProbe, ask_);
  std::vector<char> buffer(kMessageBytes);
  MPI_Request request;
  const auto post = [&] {
    MPI_Irecv(buffer.data(), kMessageBytes, MPI_BYTE, MPI_ANY_SOURCE, MPI_ANY_TAG, ask_, &request);
  };
  post();
  const double deadline = MPI_Wtime() + 0.4;
  while (MPI_Wtime() < deadline) {
    int got = 0;
    MPI_Status status;
    MPI_Test(&request, &got, &status);
    if (!got) {
      usleep(500);
      continue;
    }
    // A rank that was itself given up on (stopped, then continued by the launcher) learns so
    // here and exits quietly.
    if (status.MPI_TAG == kProbeAnswer) answered[size_t(status.MPI_SOURCE)] = 1;
    handle(status, buffer);
    post();
  }
  std::vector<int> lost;
  int lowest_live = -1;
  for (int r = 0; r < size_; ++r) {
    if (!answered[size_t(r)])
      lost.push_back(r);
    else if (lowest_live < 0)
      lowest_live = r;
  }
  if (!lost.empty() && lowest_live == rank_ && !quitting.exchange(true)) {
    std::fprintf(stderr,
                 "strata: error: --distributed: %s %s lost (no answer; the MPI launcher is "
                 "ending the job)\n",
                 rankList(lost).c_str(), lost.size() == 1 ? "was" : "were");
    std::fflush(stderr);
  }
  // The process ends as SIGTERM would have ended it (removing its temporary files).
  ::sigaction(SIGTERM, &previous_term, nullptr);
  std::raise(SIGTERM);
  _exit(143);
}

void RankWatch::wait(MPI_Request& request, const char* what) {
  if (!active_) {
    MPI_Wait(&request, MPI_STATUS_IGNORE);
    return;
  }
  const double start = MPI_Wtime();
  const double interval = std::min(1.0, timeout_s_ / 4.0);
  std::vector<double> heard(size_t(size_), start);
  double next_ping = start + interval;
  int idle = 0;
  for (;;) {
    int done = 0;
    MPI_Test(&request, &done, MPI_STATUS_IGNORE);
    if (done) return;
    for (;;) {
      int got = 0;
      MPI_Status status;
      MPI_Test(&pong_, &got, &status);
      if (!got) break;
      heard[size_t(status.MPI_SOURCE)] = MPI_Wtime();
      MPI_Irecv(&pong_buffer_, int(sizeof(pong_buffer_)), MPI_BYTE, MPI_ANY_SOURCE, kPong, reply_,
                &pong_);
    }
    const double now = MPI_Wtime();
    if (now >= next_ping) {
      for (int r = 0; r < size_; ++r)
        if (r != rank_) sendToken(r, kPing, ask_);
      next_ping = now + interval;
    }
    if (now - start > timeout_s_) {
      std::vector<int> silent;
      for (int r = 0; r < size_; ++r)
        if (r != rank_ && now - heard[size_t(r)] > timeout_s_) silent.push_back(r);
      if (!silent.empty()) giveUp(silent, what, now - start);
    }
    idleBriefly(idle);
  }
}

void RankWatch::giveUp(const std::vector<int>& silent, const char* what, double waited) {
  if (quitting.exchange(true))
    for (;;) ::pause();
  std::vector<char> is_silent(size_t(size_), 0);
  for (int r : silent) is_silent[size_t(r)] = 1;
  int printer = 0;
  while (is_silent[size_t(printer)]) ++printer;
  char line[512];
  std::snprintf(line, sizeof(line),
                "--distributed: %s stopped answering (a process stopped, hung or lost): rank %d "
                "waited %.0f s for it in %s; every rank gives up (--rank-timeout sets the wait)",
                rankList(silent).c_str(), rank_, waited, what);
  quitAll(line, printer, is_silent);
}

void RankWatch::failAlone(const std::string& line) {
  if (!active_) {
    std::fprintf(stderr, "strata: error: %s\n", line.c_str());
    std::fflush(stderr);
    removeTemporaryFilesNow();
    MPI_Abort(MPI_COMM_WORLD, 1);
    _exit(1);
  }
  if (quitting.exchange(true))
    for (;;) ::pause();
  quitAll(line.substr(0, kMessageBytes - sizeof(int) - 1), rank_,
          std::vector<char>(size_t(size_), 0));
}

void RankWatch::quitAll(const std::string& line, int printer, const std::vector<char>& is_silent) {
  // Every rank is told and exits, `printer` printing the line; a silent one finds the message if
  // it is ever continued.
  std::vector<char> message(sizeof(int) + line.size() + 1);
  std::memcpy(message.data(), &printer, sizeof(int));
  std::memcpy(message.data() + sizeof(int), line.c_str(), line.size() + 1);
  std::vector<MPI_Request> sends;
  for (int r = 0; r < size_; ++r)
    if (r != rank_) {
      sends.emplace_back();
      MPI_Isend(message.data(), int(message.size()), MPI_BYTE, r, kQuit, ask_, &sends.back());
    }
  const double deadline = MPI_Wtime() + 2.0;
  int done = 0;
  // The silent ranks' messages may never be taken: only the live ones' are waited for.
  std::vector<MPI_Request> live;
  for (int r = 0, i = 0; r < size_; ++r)
    if (r != rank_) {
      if (is_silent[size_t(r)])
        MPI_Request_free(&sends[size_t(i)]);
      else
        live.push_back(sends[size_t(i)]);
      ++i;
    }
  sends = live;
  while (!done && MPI_Wtime() < deadline) {
    MPI_Testall(int(sends.size()), sends.data(), &done, MPI_STATUSES_IGNORE);
    if (!done) usleep(1000);
  }
  printAndExit(line.c_str(), printer == rank_, 1);
}

}  // namespace strata

#endif
