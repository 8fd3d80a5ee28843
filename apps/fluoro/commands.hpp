#pragma once
// Each subcommand adds itself to the program; its callback does the work and may throw
// InputError (exit 2) or anything else (exit 1). main.cpp owns the error policy.
#include <CLI/CLI.hpp>
#include <stdexcept>

namespace fluoro::cli {

void add_info_command(CLI::App& app);
void add_drr_command(CLI::App& app);
void add_phantom_command(CLI::App& app);
void add_demo_command(CLI::App& app);
void add_devices_command(CLI::App& app);
void add_prepare_command(CLI::App& app);
void add_register_command(CLI::App& app);
void add_sweep_command(CLI::App& app);
void add_pivot_command(CLI::App& app);
void add_register_points_command(CLI::App& app);
void add_icp_command(CLI::App& app);
void add_calibrate_command(CLI::App& app);
void add_dewarp_command(CLI::App& app);
void add_panorama_command(CLI::App& app);
void add_measure_command(CLI::App& app);
void add_distal_lock_command(CLI::App& app);

// Readable input that defeated the method (a registration, a calibration, a fit): the result file
// was written with status "failed" and says why; exit code 3.
class MethodFailed : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Leave with `code` and print nothing: another process of the same job already said why (the
// ranks of an MPI sweep other than rank 0).
struct ExitQuietly {
  int code;
};

}  // namespace fluoro::cli
