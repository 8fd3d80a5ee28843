// `fluoro sweep` over the ranks of an MPI job. Every rank prepares the scene once; rank 0 owns the
// runs file and hands runs out on request, a few at a time, so a rank that draws slow runs (far
// starts take 5-10x longer) asks less often and no rank idles while runs remain. Rank 0 also runs
// runs itself. Each finished run travels to rank 0 as its row and is appended and flushed at once:
// a rank that dies loses only its runs in flight, which the resume rule redoes on a rerun.
//
// Threads: only each rank's main thread calls MPI (MPI_THREAD_FUNNELED); runs execute on worker
// threads, as many as the rank's cores (its oneTBB concurrency, which follows the launcher's
// binding). The main threads poll with a 1 ms sleep rather than block in MPI_Recv, which in
// Open MPI spins and would take a core from the runs.
#include <mpi.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <mutex>
#include <thread>
#include <type_traits>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/result_files.hpp"
#include "apps/fluoro/sweep_session.hpp"
#include "engine/error.hpp"
#include "engine/thread_limit.hpp"

namespace fluoro::cli {
namespace {

static_assert(std::is_trivially_copyable_v<SweepRow>, "rows travel between ranks as bytes");

enum Tag : int {
  kRequest = 1,  // worker -> 0: int, how many runs it can take
  kWork = 2,     // 0 -> worker: int[] plan indices; empty: no runs left
  kRow = 3,      // worker -> 0: one SweepRow
  kDone = 4,     // worker -> 0: no run in flight and none will come
  kStatus = 5,   // 0 -> all (broadcast): int, 0 to go on, else the exit code to leave with
};

void pause_briefly() { std::this_thread::sleep_for(std::chrono::milliseconds(1)); }

// One worker per core of the rank, or fewer under `--threads N`: oneTBB's arena concurrency does not
// follow tbb::global_control, so the limit in force (engine/thread_limit.hpp) is applied here.
int worker_count() { return std::max(1, std::min(tbb::this_task_arena::max_concurrency(), thread_limit())); }

// Runs taken from a queue by `threads` workers; the finished rows are collected for the main
// thread (which alone talks MPI).
class LocalRunner {
 public:
  LocalRunner(const SweepScene& scene, const std::vector<SweepRun>& plan, int threads) : scene_(scene), plan_(plan) {
    for (int t = 0; t < threads; ++t) workers_.emplace_back([this] { work(); });
  }
  ~LocalRunner() {
    close();
    for (auto& w : workers_) w.join();
  }
  void add(const std::vector<int>& indices) {
    std::lock_guard lock(m_);
    queue_.insert(queue_.end(), indices.begin(), indices.end());
    cv_.notify_all();
  }
  void close() {
    std::lock_guard lock(m_);
    closed_ = true;
    cv_.notify_all();
  }
  // Runs queued or running.
  size_t load() {
    std::lock_guard lock(m_);
    return queue_.size() + running_;
  }
  bool idle() { return load() == 0; }
  std::vector<SweepRow> take_rows() {
    std::lock_guard lock(m_);
    std::vector<SweepRow> rows(finished_.begin(), finished_.end());
    finished_.clear();
    return rows;
  }
  int threads() const { return int(workers_.size()); }

 private:
  void work() {
    for (;;) {
      int index;
      {
        std::unique_lock lock(m_);
        cv_.wait(lock, [&] { return closed_ || !queue_.empty(); });
        if (queue_.empty()) return;
        index = queue_.front();
        queue_.pop_front();
        ++running_;
      }
      const SweepRow row = scene_.run(plan_[size_t(index)]);
      std::lock_guard lock(m_);
      finished_.push_back(row);
      --running_;
    }
  }

  const SweepScene& scene_;
  const std::vector<SweepRun>& plan_;
  std::mutex m_;
  std::condition_variable cv_;
  std::deque<int> queue_;
  std::deque<SweepRow> finished_;
  size_t running_ = 0;
  bool closed_ = false;
  std::vector<std::thread> workers_;
};

// Rank 0: serves requests, writes rows, and runs runs on its own cores.
void coordinate(const SweepOptions& o, const SweepScene& scene, const std::vector<SweepRun>& plan,
                SweepProgress& progress, int ranks) {
  std::deque<int> unassigned;
  for (const SweepRun& r : progress.pending) unassigned.push_back(r.index);
  SweepRowWriter writer(o, progress);
  LocalRunner local(scene, plan, worker_count());
  int workers_active = ranks - 1;
  // Keep rank 0's own queue short so that the runs left at the end go to whoever is free.
  auto feed_local = [&] {
    while (!unassigned.empty() && local.load() < size_t(local.threads())) {
      local.add({unassigned.front()});
      unassigned.pop_front();
    }
  };
  for (;;) {
    bool busy = false;
    feed_local();
    for (const SweepRow& row : local.take_rows()) writer.add(row), busy = true;
    int flag = 0;
    MPI_Status status;
    MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &status);
    if (flag) {
      busy = true;
      if (status.MPI_TAG == kRequest) {
        int wanted = 0;
        MPI_Recv(&wanted, 1, MPI_INT, status.MPI_SOURCE, kRequest, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        std::vector<int> work;
        while (!unassigned.empty() && int(work.size()) < wanted) {
          work.push_back(unassigned.front());
          unassigned.pop_front();
        }
        MPI_Send(work.data(), int(work.size()), MPI_INT, status.MPI_SOURCE, kWork, MPI_COMM_WORLD);
      } else if (status.MPI_TAG == kRow) {
        SweepRow row;
        MPI_Recv(&row, int(sizeof row), MPI_BYTE, status.MPI_SOURCE, kRow, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        writer.add(row);
      } else if (status.MPI_TAG == kDone) {
        MPI_Recv(nullptr, 0, MPI_INT, status.MPI_SOURCE, kDone, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        --workers_active;
      }
    }
    if (workers_active == 0 && unassigned.empty() && local.idle()) {
      for (const SweepRow& row : local.take_rows()) writer.add(row);
      break;
    }
    if (!busy) pause_briefly();
  }
  writer.finish();
}

// Ranks 1..n-1: ask for as many runs as there are free workers, run them, send the rows back.
void serve(const SweepScene& scene, const std::vector<SweepRun>& plan) {
  LocalRunner local(scene, plan, worker_count());
  bool asked = false, no_more = false;
  for (;;) {
    bool busy = false;
    for (SweepRow& row : local.take_rows()) {
      MPI_Send(&row, int(sizeof row), MPI_BYTE, 0, kRow, MPI_COMM_WORLD);
      busy = true;
    }
    const size_t load = local.load();
    if (!no_more && !asked && load < size_t(local.threads())) {
      const int wanted = local.threads() - int(load);
      MPI_Send(&wanted, 1, MPI_INT, 0, kRequest, MPI_COMM_WORLD);
      asked = true;
    }
    if (asked) {
      int flag = 0;
      MPI_Status status;
      MPI_Iprobe(0, kWork, MPI_COMM_WORLD, &flag, &status);
      if (flag) {
        int count = 0;
        MPI_Get_count(&status, MPI_INT, &count);
        std::vector<int> work(static_cast<size_t>(std::max(count, 0)));
        MPI_Recv(work.data(), count, MPI_INT, 0, kWork, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        asked = false;
        busy = true;
        if (work.empty()) no_more = true;
        else local.add(work);
      }
    }
    if (no_more && local.idle()) {
      for (SweepRow& row : local.take_rows()) MPI_Send(&row, int(sizeof row), MPI_BYTE, 0, kRow, MPI_COMM_WORLD);
      MPI_Send(nullptr, 0, MPI_INT, 0, kDone, MPI_COMM_WORLD);
      return;
    }
    if (!busy) pause_briefly();
  }
}

// The MPI library's lifetime: initialised for this command, finalised on every normal way out.
struct MpiSession {
  MpiSession() {
    int provided = 0;
    MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
  }
  ~MpiSession() { MPI_Finalize(); }
  int rank = 0, size = 1;
};

// Rank 0 tells every rank whether to go on (0) or leave with an exit code: errors in the
// configuration or the runs file are found once, reported once.
int broadcast_status(int status) {
  MPI_Bcast(&status, 1, MPI_INT, 0, MPI_COMM_WORLD);
  return status;
}

// A rank's error after the start (a CT unreadable from one node, say): its one line, then the
// whole job ends, since the others would wait for it forever.
[[noreturn]] void abort_job(const char* what, int code) {
  std::fprintf(stderr, "fluoro: %s\n", what);
  std::fflush(stderr);
  MPI_Abort(MPI_COMM_WORLD, code);
  std::exit(code);
}

}  // namespace

bool run_sweep_on_mpi_ranks(const SweepOptions& o) {
  MpiSession mpi;
  if (mpi.size == 1) return false;
  // Configuration and resume on rank 0 first; the others read the (now known good) configuration.
  SweepProgress progress;
  std::vector<SweepRun> plan;
  if (mpi.rank == 0) {
    try {
      plan = plan_sweep(sweep_config(o));
      progress = resume_sweep(o, plan);
    } catch (...) {
      broadcast_status(2);
      throw;  // main() prints the one line
    }
    broadcast_status(progress.pending.empty() ? -1 : 0);
  } else {
    const int status = broadcast_status(0);
    if (status == -1) return true;
    if (status != 0) throw ExitQuietly{status};
  }
  const auto t0 = std::chrono::steady_clock::now();
  if (mpi.rank == 0 && progress.pending.empty()) {
    finish_sweep(o, progress.rows, seconds_since(t0), 0, mpi.size);
    return true;
  }
  try {
    const SweepConfig config = sweep_config(o);
    if (mpi.rank != 0) plan = plan_sweep(config);
    const SweepScene scene(config);
    if (mpi.rank == 0) {
      if (!o.quiet)
        std::fprintf(stderr, "sweep: %d MPI ranks, scene prepared in %.2f s on rank 0\n", mpi.size,
                     scene.preparation_seconds());
      coordinate(o, scene, plan, progress, mpi.size);
    } else {
      serve(scene, plan);
    }
  } catch (const InputError& e) {
    abort_job(e.what(), 2);
  } catch (const std::exception& e) {
    abort_job((std::string("internal error: ") + e.what()).c_str(), 1);
  }
  if (mpi.rank == 0) finish_sweep(o, progress.rows, seconds_since(t0), progress.pending.size(), mpi.size);
  return true;
}

}  // namespace fluoro::cli
