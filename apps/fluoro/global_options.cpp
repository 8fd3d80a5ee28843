#include "apps/fluoro/global_options.hpp"

#include <cstdio>

#include "engine/thread_limit.hpp"
#include "engine/version.hpp"
#include "kernels/cpu/simd_targets.hpp"

namespace fluoro::cli {
namespace {

struct GlobalOptions {
  int threads = 0;  // 0: as many as oneTBB finds cores
  std::string simd;  // empty: the best set the CPU runs
  bool quiet = false, verbose = false;
  std::vector<std::string> arguments;
};

GlobalOptions& options() {
  static GlobalOptions o;
  return o;
}

// Runs after parsing, before the subcommand's callback: the limits are in place before any work.
void apply() {
  const GlobalOptions& o = options();
  if (o.threads > 0) limit_threads(o.threads);
  if (!o.simd.empty()) cpu::limit_simd(o.simd);  // the option's check already matched a name
  // Every line a command prints on success goes to stdout (errors and progress go to stderr):
  // closing it is the one place that keeps -q true for every command, present and future.
  if (o.quiet && !std::freopen("/dev/null", "w", stdout)) std::fclose(stdout);
  if (o.verbose)
    std::fprintf(stderr, "fluoro %s: at most %d threads (oneTBB, OpenCV, ITK, lavapipe), cpu kernels on %s\n", kVersion,
                 thread_limit(), cpu::simd_target().c_str());
}

}  // namespace

void add_global_options(CLI::App& app, int argc, char** argv) {
  for (int i = 1; i < argc; ++i) options().arguments.emplace_back(argv[i]);
  app.fallthrough();
  app.add_option("--threads", options().threads, "Use at most N threads (default: all cores)")
      ->check(CLI::Range(1, 4096));
  app.add_option("--simd", options().simd,
                 "Run the cpu backend's kernels on at most this SIMD set (default: the best the CPU has; "
                 "fluoro devices lists them)")
      ->check(CLI::IsMember(cpu::simd_targets(), CLI::ignore_case));
  auto* q = app.add_flag("-q,--quiet", options().quiet, "Print nothing on success (errors still print their one line)");
  auto* v = app.add_flag("-v,--verbose", options().verbose,
                         "Also print the version, the thread limit, the cpu SIMD set, the inputs' SHA-256 and the time, on stderr");
  q->excludes(v);
  app.parse_complete_callback(apply);
}

void name_global_options_in_help(CLI::App& app) {
  for (CLI::App* sub : app.get_subcommands({})) {
    sub->footer("Options of every command, before or after its name (fluoro --help): --threads N, --simd NAME, "
                "-q/--quiet, -v/--verbose");
    name_global_options_in_help(*sub);
  }
}

bool quiet() { return options().quiet; }
bool verbose() { return options().verbose; }
const std::vector<std::string>& arguments() { return options().arguments; }

}  // namespace fluoro::cli
