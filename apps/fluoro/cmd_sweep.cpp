// fluoro sweep: robustness sweep of the registration from start poses at controlled distances
// (seed, chapter 2, fig. 7). Rows are appended as runs finish, so a stopped sweep resumes where it
// left off; a line cut short by a crash is dropped on restart.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/global_options.hpp"
#include "engine/atomic_file.hpp"
#include "engine/error.hpp"
#include "pipelines/registration/sweep.hpp"

namespace fluoro::cli {
namespace {

struct SweepOptions {
  std::string config, out, plot;
  bool quiet = false;
};

void write_text_atomic(const std::string& path, const std::string& text) {
  write_file_atomic(path, [&](const std::string& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    f << text;
    if (!f.flush()) throw_input_error(path, "cannot write");
  });
}

void run(const SweepOptions& o) {
  const SweepConfig config = read_sweep_config(o.config);
  const std::vector<SweepRun> plan = plan_sweep(config);
  // Resume: keep the rows already written (they must be this sweep's), rewrite the file without
  // a line a crash may have cut short, then append.
  std::vector<SweepRow> rows = read_sweep_csv(o.out);
  std::set<int> done;
  for (const SweepRow& r : rows) {
    if (r.run.index < 0 || size_t(r.run.index) >= plan.size() || plan[size_t(r.run.index)].seed != r.run.seed ||
        plan[size_t(r.run.index)].distance_mm != r.run.distance_mm)
      throw_input_error(o.out, "holds runs of a different sweep configuration (run " + std::to_string(r.run.index) +
                                   "); remove it or choose another --out");
    done.insert(r.run.index);
  }
  std::string existing = sweep_csv_header() + "\n";
  for (const SweepRow& r : rows) existing += sweep_csv_row(r) + "\n";
  write_text_atomic(o.out, existing);
  std::vector<SweepRun> pending;
  for (const SweepRun& r : plan)
    if (!done.count(r.index)) pending.push_back(r);

  const bool terminal = !o.quiet && isatty(2);
  if (!o.quiet)
    std::fprintf(stderr, "sweep: %zu runs planned, %zu already in %s, %zu to run\n", plan.size(), done.size(),
                 o.out.c_str(), pending.size());
  const auto t0 = std::chrono::steady_clock::now();
  if (!pending.empty()) {
    const SweepScene scene(config);
    if (!o.quiet) std::fprintf(stderr, "sweep: scene prepared in %.2f s\n", scene.preparation_seconds());
    std::ofstream csv(o.out, std::ios::app);
    if (!csv) throw_input_error(o.out, "cannot open for appending");
    size_t finished = 0, successes = 0;
    run_sweep(scene, pending, [&](const SweepRow& row) {
      csv << sweep_csv_row(row) << '\n';
      csv.flush();
      rows.push_back(row);
      ++finished;
      successes += row.success;
      if (terminal) {
        const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        const double eta = elapsed / double(finished) * double(pending.size() - finished);
        const int filled = int(30.0 * double(finished) / double(pending.size()));
        std::fprintf(stderr, "\r[%-30s] %zu/%zu runs, %.1f%% success, %.0f s left   ",
                     std::string(size_t(filled), '#').c_str(), finished, pending.size(),
                     100.0 * double(successes) / double(finished), eta);
      }
    });
    if (terminal) std::fprintf(stderr, "\n");
    if (!csv) throw_input_error(o.out, "write failed");
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!o.plot.empty()) write_text_atomic(o.plot, sweep_plot_svg(rows));
  if (!o.quiet) {
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
                "per run, wall %.1f s for %zu new runs\n",
                o.out.c_str(), n, n ? 100.0 * double(s) / double(n) : 0.0, n40 ? 100.0 * double(s40) / double(n40) : 0.0,
                s ? tre / double(s) : 0.0, n ? seconds / double(n) : 0.0, wall, pending.size());
  }
}

}  // namespace

void add_sweep_command(CLI::App& app) {
  auto o = std::make_shared<SweepOptions>();
  auto* cmd = app.add_subcommand("sweep", "Registration robustness sweep from start poses at controlled distances");
  cmd->add_option("--config", o->config, "Sweep configuration JSON (docs/cli.md)")->required();
  cmd->add_option("--out", o->out, "Runs CSV (appended; a stopped sweep resumes)")->required();
  cmd->add_option("--plot", o->plot, "SVG plot: final TRE, cumulative failures and time against distance");
  cmd->callback([o] {
    o->quiet = quiet();  // the program's -q/--quiet (global_options.hpp)
    run(*o);
  });
}

}  // namespace fluoro::cli
