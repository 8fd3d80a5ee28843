// fluoro: the command-line front end. Thin: parsing and error policy here, the work in the
// engine and pipelines. Exit codes: 0 ok, 1 internal failure, 2 bad input, 3 readable input that
// defeated the method (the result file says why; docs/cli.md).
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/global_options.hpp"
#include "engine/error.hpp"
#include "engine/version.hpp"

int main(int argc, char** argv) {
  CLI::App app{"fluoro: fluoroscopic X-ray image guidance engine (DRRs, gradient projection, phantoms)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("fluoro ") + fluoro::kVersion);
  const auto start = std::chrono::steady_clock::now();
  fluoro::cli::add_global_options(app, argc, argv);  // first: the subcommands inherit its fallthrough
  fluoro::cli::add_info_command(app);
  fluoro::cli::add_drr_command(app);
  fluoro::cli::add_phantom_command(app);
  fluoro::cli::add_demo_command(app);
  fluoro::cli::add_prepare_command(app);
  fluoro::cli::add_register_command(app);
  fluoro::cli::add_sweep_command(app);
  fluoro::cli::add_calibrate_command(app);
  fluoro::cli::add_devices_command(app);
  fluoro::cli::add_pivot_command(app);
  fluoro::cli::add_register_points_command(app);
  fluoro::cli::add_icp_command(app);
  fluoro::cli::add_dewarp_command(app);
  fluoro::cli::add_panorama_command(app);
  fluoro::cli::add_measure_command(app);
  fluoro::cli::add_distal_lock_command(app);
  fluoro::cli::name_global_options_in_help(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line, like every other bad input.
    std::fprintf(stderr, "fluoro: %s (see fluoro --help)\n", e.what());
    return 2;
  } catch (const std::filesystem::filesystem_error& e) {
    // A path the user gave that the file system refused (permissions, not a directory, ...).
    std::fprintf(stderr, "fluoro: %s\n", e.what());
    return 2;
  } catch (const fluoro::cli::ExitQuietly& e) {
    return e.code;
  } catch (const fluoro::cli::MethodFailed& e) {
    std::fprintf(stderr, "fluoro: %s\n", e.what());
    return 3;
  } catch (const fluoro::InputError& e) {
    std::fprintf(stderr, "fluoro: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fluoro: internal error: %s\n", e.what());
    return 1;
  }
  if (fluoro::cli::verbose())
    std::fprintf(stderr, "fluoro: done in %.3f s\n",
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return 0;
}
