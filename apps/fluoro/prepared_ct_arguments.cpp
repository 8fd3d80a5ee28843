#include "apps/fluoro/prepared_ct_arguments.hpp"

#include <cmath>

#include "engine/error.hpp"
#include "engine/sha256.hpp"

namespace fluoro::cli {

void add_preparation_options(CLI::App& cmd, PreparationArguments& a) {
  cmd.add_option("--iso", a.iso_hu, "Bone iso-value of the coarse step's mesh, HU")->capture_default_str();
  cmd.add_option("--tissue-hu", a.tissue_hu, "The fine step's gradient field keeps attenuation above this (soft tissue), HU")
      ->capture_default_str();
  cmd.add_option("--mu-water", a.mu_water, "Attenuation of water, 1/mm")->capture_default_str();
}

void validate_preparation_arguments(const PreparationArguments& a) {
  if (!std::isfinite(a.iso_hu)) throw_input_error("--iso", "must be a number");
  if (!std::isfinite(a.tissue_hu)) throw_input_error("--tissue-hu", "must be a number");
  if (!(a.mu_water > 0) || !std::isfinite(a.mu_water)) throw_input_error("--mu-water", "must be a positive number");
}

RegistrationOptions registration_options(const PreparationArguments& a) {
  RegistrationOptions options;
  options.bone_iso_hu = a.iso_hu;
  options.tissue_hu = a.tissue_hu;
  options.mu_water_per_mm = a.mu_water;
  return options;
}

PreparedCtSource prepared_ct_source(const PreparationArguments& a, const RegistrationOptions& options) {
  PreparedCtSource s;
  s.ct_path = a.ct;
  s.ct_sha256 = sha256_of_input(a.ct);
  if (!a.mask.empty()) {
    s.mask_path = a.mask;
    s.mask_sha256 = sha256_of_input(a.mask);
  }
  s.settings = preparation_settings(options, !a.mask.empty());
  return s;
}

}  // namespace fluoro::cli
