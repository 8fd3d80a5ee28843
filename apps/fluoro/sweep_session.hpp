#pragma once
// What a sweep run in one process and a sweep spread over MPI ranks share: the options, the runs
// file's resume rule, the row writer and the closing summary. Rows are appended as runs finish,
// so a stopped sweep resumes where it left off; a line cut short by a crash is dropped on restart.
#include <chrono>
#include <fstream>
#include <string>
#include <vector>

#include "pipelines/sweep/sweep.hpp"

namespace fluoro::cli {

struct SweepOptions {
  std::string config, out, plot;
  std::string summary;    // --summary: the per-distance summary CSV; default summary_path(out)
  std::string summarize;  // --summarize RUNS.csv: summarise an existing runs file, run nothing
  std::string prepared;  // --prepared: replaces the config's "prepared"
  std::string confidence_log;  // --confidence-log: each run's confidence ingredients, JSON lines
  bool quiet = false;
};

// The sweep's configuration (read_sweep_config) with the command line's overrides.
SweepConfig sweep_config(const SweepOptions& o);

// The runs file of a sweep being started or resumed: the rows already in it (checked to be this
// sweep's runs) and the runs still to do. The file is rewritten without a line a crash cut short.
struct SweepProgress {
  std::vector<SweepRow> rows;
  std::vector<SweepRun> pending;
};
SweepProgress resume_sweep(const SweepOptions& o, const std::vector<SweepRun>& plan);

// Appends each finished run to the runs file (flushed at once: a stop loses no finished run) and
// draws a progress bar when stderr is a terminal. Not thread-safe: callers serialise add().
class SweepRowWriter {
 public:
  SweepRowWriter(const SweepOptions& o, SweepProgress& progress);
  void add(const SweepRow& row);
  void finish();  // ends the progress line; throws InputError if a write failed

 private:
  const SweepOptions& options_;
  SweepProgress& progress_;
  std::ofstream csv_;
  bool terminal_;
  size_t to_run_, finished_ = 0, successes_ = 0;
  std::chrono::steady_clock::time_point t0_ = std::chrono::steady_clock::now();
};

// Where the per-distance summary of the runs file `runs_csv` goes by default: beside it, the same
// name with "_summary.csv" for its extension (runs.csv -> runs_summary.csv).
std::string summary_path(const std::string& runs_csv);

// Writes the per-distance summary CSV and the plot (if asked), and prints the one-line summary and
// the per-distance table (unless quiet).
void finish_sweep(const SweepOptions& o, const std::vector<SweepRow>& rows, double wall_seconds, size_t new_runs,
                  int ranks);

// `fluoro sweep --summarize RUNS.csv`: the summary, table and plot of an existing runs file.
void summarize_runs_file(const SweepOptions& o);

// True when this process was started by an MPI launcher (mpirun, mpiexec, srun).
bool launched_as_mpi_job();
// The sweep distributed over the ranks of the MPI job (apps/fluoro/sweep_mpi.cpp), called on every
// rank. False (nothing done) when the job has a single rank: the caller then runs the sweep itself.
bool run_sweep_on_mpi_ranks(const SweepOptions& o);

}  // namespace fluoro::cli
