#include "apps/fluoro/physics_options.hpp"

#include <string>

#include "engine/error.hpp"

namespace fluoro::cli {

void add_physics_options(CLI::App* cmd, XrayPhysics& p) {
  const char* group = "Imaging physics (each off by default; docs/cli.md)";
  cmd->add_option("--beam-hardening", p.beam_hardening,
                  "Beam-hardening coefficient b: the line integral L (scaled to at most 6) becomes L - b L^2 (e.g. 0.06)")
      ->group(group);
  cmd->add_option("--scatter", p.scatter_to_primary,
                  "Scatter-to-primary ratio: a wide blur (40 px at 512 px) of the primary intensity added (e.g. 0.25)")
      ->group(group);
  cmd->add_option("--blur-px", p.blur_px, "Detector blur, Gaussian sigma in pixels (e.g. 1)")->group(group);
  cmd->add_option("--photons", p.photons, "Poisson quantum noise: photons per open-beam pixel (e.g. 20000)")->group(group);
  cmd->add_option("--physics-seed", p.seed, "Seed of the quantum noise")->capture_default_str()->group(group);
}

void check_physics_options(const XrayPhysics& p) {
  const auto bad = xray_physics_problem(p);
  if (!bad) return;
  // The library names SWEEP.json's keys; the command line spells them as options.
  std::string option = "--" + bad->key;
  for (char& c : option)
    if (c == '_') c = '-';
  if (bad->key == "scatter_sigma_px" || bad->key == "max_line_integral") option = "x-ray physics (" + bad->key + ")";
  throw_input_error(option, bad->problem);
}

nlohmann::json physics_settings(const XrayPhysics& p) {
  return {{"beam_hardening", p.beam_hardening}, {"scatter", p.scatter_to_primary}, {"blur_px", p.blur_px},
          {"photons", p.photons}, {"physics_seed", p.seed}};
}

}  // namespace fluoro::cli
