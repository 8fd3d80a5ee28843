#pragma once
// The imaging-physics options of the commands that make X-rays (fluoro demo, fluoro drr):
// --beam-hardening, --scatter, --blur-px, --photons, --physics-seed (datasets/xray_physics.hpp).
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "datasets/xray_physics.hpp"

namespace fluoro::cli {

void add_physics_options(CLI::App* cmd, XrayPhysics& physics);

// Throws InputError naming the option of a parameter out of range.
void check_physics_options(const XrayPhysics& physics);

// The settings, for a result file's provenance.
nlohmann::json physics_settings(const XrayPhysics& physics);

}  // namespace fluoro::cli
