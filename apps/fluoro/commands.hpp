#pragma once
// Each subcommand adds itself to the program; its callback does the work and may throw
// InputError (exit 2) or anything else (exit 1). main.cpp owns the error policy.
#include <CLI/CLI.hpp>

namespace fluoro::cli {

void add_info_command(CLI::App& app);
void add_drr_command(CLI::App& app);
void add_phantom_command(CLI::App& app);
void add_demo_command(CLI::App& app);
void add_devices_command(CLI::App& app);

}  // namespace fluoro::cli
