#include "apps/fluoro/sweep_session.hpp"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <set>

#include "apps/fluoro/result_files.hpp"
#include "engine/atomic_file.hpp"
#include "engine/error.hpp"
#include "pipelines/sweep/sweep_summary.hpp"

namespace fluoro::cli {
namespace {

void write_text_atomic(const std::string& path, const std::string& text) {
  write_file_atomic(path, [&](const std::string& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    f << text;
    if (!f.flush()) throw_input_error(path, "cannot write");
  });
}

}  // namespace

SweepConfig sweep_config(const SweepOptions& o) {
  SweepConfig c = read_sweep_config(o.config);
  if (!o.prepared.empty()) c.prepared_path = o.prepared;
  // Before the runs file is touched (the scene would refuse it too, later).
  if (!c.prepared_path.empty() && c.ct_path.empty())
    throw_input_error(c.prepared_path, "a prepared CT needs the sweep's \"ct\" it was prepared from, not a phantom");
  return c;
}

SweepProgress resume_sweep(const SweepOptions& o, const std::vector<SweepRun>& plan) {
  SweepProgress p;
  p.rows = read_sweep_csv(o.out);
  std::set<int> done;
  for (const SweepRow& r : p.rows) {
    if (r.run.index < 0 || size_t(r.run.index) >= plan.size() || plan[size_t(r.run.index)].seed != r.run.seed ||
        plan[size_t(r.run.index)].distance_mm != r.run.distance_mm)
      throw_input_error(o.out, "holds runs of a different sweep configuration (run " + std::to_string(r.run.index) +
                                   "); remove it or choose another --out");
    done.insert(r.run.index);
  }
  std::string existing = sweep_csv_header() + "\n";
  for (const SweepRow& r : p.rows) existing += sweep_csv_row(r) + "\n";
  write_text_atomic(o.out, existing);
  for (const SweepRun& r : plan)
    if (!done.count(r.index)) p.pending.push_back(r);
  if (!o.quiet)
    std::fprintf(stderr, "sweep: %zu runs planned, %zu already in %s, %zu to run\n", plan.size(), done.size(),
                 o.out.c_str(), p.pending.size());
  return p;
}

SweepRowWriter::SweepRowWriter(const SweepOptions& o, SweepProgress& progress)
    : options_(o), progress_(progress), csv_(o.out, std::ios::app), terminal_(!o.quiet && isatty(2)),
      to_run_(progress.pending.size()) {
  if (!csv_) throw_input_error(o.out, "cannot open for appending");
}

void SweepRowWriter::add(const SweepRow& row) {
  csv_ << sweep_csv_row(row) << '\n';
  csv_.flush();
  progress_.rows.push_back(row);
  ++finished_;
  successes_ += row.success;
  if (terminal_) {
    const double elapsed = seconds_since(t0_);
    const double eta = elapsed / double(finished_) * double(to_run_ - std::min(finished_, to_run_));
    const int filled = int(30.0 * double(std::min(finished_, to_run_)) / double(std::max<size_t>(to_run_, 1)));
    std::fprintf(stderr, "\r[%-30s] %zu/%zu runs, %.1f%% success, %.0f s left   ",
                 std::string(size_t(filled), '#').c_str(), finished_, to_run_,
                 100.0 * double(successes_) / double(finished_), eta);
  }
}

void SweepRowWriter::finish() {
  if (terminal_ && finished_ > 0) std::fprintf(stderr, "\n");
  if (!csv_) throw_input_error(options_.out, "write failed");
}

std::string summary_path(const std::string& runs_csv) {
  std::filesystem::path p(runs_csv);
  p.replace_filename(p.stem().string() + "_summary.csv");
  return p.string();
}

namespace {

// The summary file, the plot and (unless quiet) the table: what a finished sweep and --summarize
// share.
void write_summary(const SweepOptions& o, const std::string& runs_csv, const std::vector<SweepRow>& rows) {
  const std::vector<SweepBinSummary> bins = summarize_sweep(rows);
  const std::string summary = o.summary.empty() ? summary_path(runs_csv) : o.summary;
  if (std::filesystem::weakly_canonical(summary) == std::filesystem::weakly_canonical(runs_csv))
    throw_input_error(summary, "is the runs file itself; give --summary another path");
  write_text_atomic(summary, sweep_summary_csv(bins));
  if (!o.plot.empty()) write_text_atomic(o.plot, sweep_plot_svg(rows));
  if (o.quiet) return;
  std::printf("%s", sweep_summary_table(bins).c_str());
  std::printf("wrote %s%s%s\n", summary.c_str(), o.plot.empty() ? "" : " and ", o.plot.c_str());
}

}  // namespace

void summarize_runs_file(const SweepOptions& o) {
  if (!std::filesystem::is_regular_file(o.summarize)) throw_input_error(o.summarize, "no such runs file");
  const std::vector<SweepRow> rows = read_sweep_csv(o.summarize);
  if (rows.empty()) throw_input_error(o.summarize, "holds no complete run");
  if (!o.quiet) std::printf("%s: %zu runs\n", o.summarize.c_str(), rows.size());
  write_summary(o, o.summarize, rows);
}

void finish_sweep(const SweepOptions& o, const std::vector<SweepRow>& rows, double wall_seconds, size_t new_runs,
                  int ranks) {
  if (o.quiet) {
    write_summary(o, o.out, rows);
    return;
  }
  // Success up to 40 mm (the robustness bar) and overall.
  size_t n40 = 0, s40 = 0, n = rows.size(), s = 0;
  double tre = 0, seconds = 0;
  for (const SweepRow& r : rows) {
    s += r.success;
    seconds += r.seconds;
    if (r.success) tre += r.final_tre_mm;
    if (r.run.distance_mm <= 40) ++n40, s40 += r.success;
  }
  std::printf("%s: %zu runs, %.1f%% success (%.1f%% up to 40 mm), mean final TRE of successes %.3f mm, mean %.2f s "
              "per run, wall %.1f s for %zu new runs",
              o.out.c_str(), n, n ? 100.0 * double(s) / double(n) : 0.0, n40 ? 100.0 * double(s40) / double(n40) : 0.0,
              s ? tre / double(s) : 0.0, n ? seconds / double(n) : 0.0, wall_seconds, new_runs);
  if (ranks > 1) std::printf(" on %d MPI ranks", ranks);
  std::printf("\n");
  write_summary(o, o.out, rows);
}

// The launchers' own variables: Open MPI's mpirun, MPICH's hydra and Slurm's PMI2 set PMI_* or
// OMPI_*, srun with PMIx sets PMIX_RANK. An sbatch script alone sets none of these, so a plain
// `fluoro sweep` inside a batch job runs as one process.
bool launched_as_mpi_job() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"})
    if (std::getenv(v)) return true;
  return false;
}

#ifndef FLUORO_HAVE_MPI
bool run_sweep_on_mpi_ranks(const SweepOptions& o) {
  // Every rank would run the whole sweep into the same file: refuse instead.
  const char* size = std::getenv("OMPI_COMM_WORLD_SIZE");
  if (!size) size = std::getenv("PMI_SIZE");
  if (size && std::atoi(size) > 1)
    throw_input_error(o.config, "this fluoro was built without MPI (libopenmpi-dev); run the sweep without mpirun/srun");
  return false;
}
#endif

}  // namespace fluoro::cli
