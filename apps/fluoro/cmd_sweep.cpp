// fluoro sweep: robustness sweep of the registration from start poses at controlled distances
// (seed, chapter 2, fig. 7), in this process over its cores, or over the ranks of an MPI job when
// started by mpirun/srun (apps/fluoro/sweep_mpi.cpp, docs/cluster.md).
#include <chrono>
#include <cstdio>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/global_options.hpp"
#include "apps/fluoro/result_files.hpp"
#include "apps/fluoro/sweep_session.hpp"

namespace fluoro::cli {
namespace {

void run(const SweepOptions& o) {
  if (launched_as_mpi_job() && run_sweep_on_mpi_ranks(o)) return;
  const SweepConfig config = sweep_config(o);
  SweepProgress progress = resume_sweep(o, plan_sweep(config));
  const auto t0 = std::chrono::steady_clock::now();
  if (!progress.pending.empty()) {
    const SweepScene scene(config);
    if (!o.quiet) std::fprintf(stderr, "sweep: scene prepared in %.2f s\n", scene.preparation_seconds());
    SweepRowWriter writer(o, progress);
    run_sweep(scene, progress.pending, [&](const SweepRow& row) { writer.add(row); });
    writer.finish();
  }
  finish_sweep(o, progress.rows, seconds_since(t0), progress.pending.size(), 1);
}

}  // namespace

void add_sweep_command(CLI::App& app) {
  auto o = std::make_shared<SweepOptions>();
  auto* cmd = app.add_subcommand("sweep", "Registration robustness sweep from start poses at controlled distances");
  cmd->add_option("--config", o->config, "Sweep configuration JSON (docs/cli.md)")->required();
  cmd->add_option("--out", o->out, "Runs CSV (appended; a stopped sweep resumes)")->required();
  cmd->add_option("--prepared", o->prepared,
                  "Prepared CT file of `fluoro prepare` for the config's \"ct\" (overrides its \"prepared\")");
  cmd->add_option("--plot", o->plot, "SVG plot: final TRE, cumulative failures and time against distance");
  cmd->callback([o] {
    o->quiet = quiet();  // the program's -q/--quiet (global_options.hpp)
    run(*o);
  });
}

}  // namespace fluoro::cli
