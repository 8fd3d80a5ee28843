// fluoro sweep: robustness sweep of the registration from start poses at controlled distances
// (seed, chapter 2, fig. 7), in this process over its cores, or over the ranks of an MPI job when
// started by mpirun/srun (apps/fluoro/sweep_mpi.cpp, docs/cluster.md).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/global_options.hpp"
#include "apps/fluoro/result_files.hpp"
#include "apps/fluoro/sweep_session.hpp"
#include "engine/error.hpp"

namespace fluoro::cli {
namespace {

// One JSON line per run: the errors that say whether it should be trusted and the confidence
// rules' ingredients, so that rules can be compared offline (docs/registration.md, "Confidence").
std::string confidence_line(const SweepRow& row) {
  const SweepRow::Confidence& c = row.confidence;
  auto finite = [](double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr); };
  nlohmann::json views = nlohmann::json::array();
  for (int v = 0; v < c.views; ++v)
    views.push_back({{"correlation", c.correlation[v]},
                     {"displaced_correlation", c.displaced_correlation[v]},
                     {"simulated_displaced", c.simulated_displaced[v]},
                     {"sharpness", c.sharpness[v]},
                     {"peak_offset", finite(c.peak_offset[v])},
                     {"expected_correlation", c.expected_correlation[v]},
                     {"measured", std::vector<double>(c.measured[v], c.measured[v] + 12)},
                     {"simulated", std::vector<double>(c.simulated[v], c.simulated[v] + 12)}});
  return nlohmann::json{{"run", row.run.index},
                        {"distance_mm", row.run.distance_mm},
                        {"final_tre_mm", row.final_tre_mm},
                        {"success", row.success},
                        {"confident", row.confident},
                        {"correlation_thresholds_met", c.correlation_thresholds_met},
                        {"gpr_pose_sharp", c.gpr_pose_sharp},
                        {"gradient_correlation", row.gradient_correlation},
                        {"correlation_floor", c.correlation_floor},
                        {"expected_correlation", c.expected_correlation_mean},
                        {"relative_correlation", c.relative_correlation},
                        {"relative_correlation_floor", c.relative_correlation_floor},
                        {"seconds", row.seconds},
                        {"peak_sharpness", {{"min_sharpness", c.min_sharpness}, {"max_peak_offset", finite(c.max_peak_offset)}, {"sharp", c.sharp},
                                            {"views", views}, {"seconds", c.seconds}}}}
      .dump();
}

void run(const SweepOptions& o) {
  if (!o.confidence_log.empty()) {
    check_output_path(o.confidence_log);
    if (launched_as_mpi_job()) throw_input_error("--confidence-log", "is written by a sweep in one process only, not over MPI ranks");
  }
  if (!o.summarize.empty()) {
    if (!o.config.empty() || !o.out.empty())
      throw_input_error("--summarize " + o.summarize, "summarises an existing runs file: give it without --config and --out");
    summarize_runs_file(o);
    return;
  }
  if (o.config.empty() || o.out.empty())
    throw_input_error("fluoro sweep", "needs --config SWEEP.json and --out RUNS.csv (or --summarize RUNS.csv)");
  if (launched_as_mpi_job() && run_sweep_on_mpi_ranks(o)) return;
  const SweepConfig config = sweep_config(o);
  SweepProgress progress = resume_sweep(o, plan_sweep(config));
  const auto t0 = std::chrono::steady_clock::now();
  if (!progress.pending.empty()) {
    const SweepScene scene(config);
    if (!o.quiet) std::fprintf(stderr, "sweep: scene prepared in %.2f s\n", scene.preparation_seconds());
    SweepRowWriter writer(o, progress);
    std::ofstream log;
    if (!o.confidence_log.empty()) log.open(o.confidence_log, std::ios::app);
    run_sweep(scene, progress.pending, [&](const SweepRow& row) {
      writer.add(row);
      if (log.is_open()) log << confidence_line(row) << '\n' << std::flush;
    });
    writer.finish();
  }
  finish_sweep(o, progress.rows, seconds_since(t0), progress.pending.size(), 1);
}

}  // namespace

void add_sweep_command(CLI::App& app) {
  auto o = std::make_shared<SweepOptions>();
  auto* cmd = app.add_subcommand("sweep", "Registration robustness sweep from start poses at controlled distances");
  cmd->add_option("--config", o->config, "Sweep configuration JSON (docs/cli.md); required unless --summarize");
  cmd->add_option("--out", o->out, "Runs CSV (appended; a stopped sweep resumes); required unless --summarize");
  cmd->add_option("--prepared", o->prepared,
                  "Prepared CT file of `fluoro prepare` for the config's \"ct\" (overrides its \"prepared\")");
  cmd->add_option("--confidence-log", o->confidence_log,
                  "Append each new run's confidence ingredients (peak sharpness per view, the former thresholds' "
                  "verdict) as one JSON line");
  cmd->add_option("--plot", o->plot,
                  "SVG plot: final TRE, cumulative failures, false-confident runs and time against distance");
  cmd->add_option("--summary", o->summary,
                  "Per-distance summary CSV (success, false-confident, confident successes); default: beside the "
                  "runs file, <name>_summary.csv");
  cmd->add_option("--summarize", o->summarize,
                  "Summarise this existing runs CSV (table, summary CSV, --plot) without running anything");
  cmd->callback([o] {
    o->quiet = quiet();  // the program's -q/--quiet (global_options.hpp)
    run(*o);
  });
}

}  // namespace fluoro::cli
