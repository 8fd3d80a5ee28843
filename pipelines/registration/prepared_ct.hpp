#pragma once
// What a registration prepares from the CT alone, before any X-ray is seen: the bone mesh of the
// coarse step, the bone-only attenuation the gradient correlation renders, and one gradient field
// per fine stage. It is the costly part of a registration's preparation, and the CT is known
// before surgery: `fluoro prepare` saves it (prepared_ct_file.hpp) so that `register` and `sweep`
// load it instead of recomputing it.
#include <memory>
#include <nlohmann/json.hpp>
#include <vector>

#include "engine/backend.hpp"
#include "pipelines/registration/bone_mesh.hpp"

namespace fluoro {

struct RegistrationOptions;

struct PreparedCt {
  BoneMesh mesh;
  std::shared_ptr<const DeviceVolume> bone_mu;                // bone's attenuation only (1/mm)
  // The rest of the CT's attenuation (the whole CT's minus bone_mu: soft tissue, air, and what a
  // mask leaves out), so that bone DRR plus its DRR is a DRR of the whole CT: the X-ray a right
  // pose would see when the X-ray holds nothing the CT lacks; its correlation with the bone DRR is
  // what a right pose scores there (RegistrationReport::expected_correlation).
  std::shared_ptr<const DeviceVolume> non_bone_mu;
  std::vector<std::shared_ptr<const DeviceVolume>> gradients;  // one per fine stage, in order
  double seconds = 0;                                          // time taken to compute or load it
};

// `hu` is the CT in HU; `mask` (optional, non-zero = bone) replaces the iso-value. Throws
// InputError for a CT without bone or a mask that covers none of it.
PreparedCt prepare_ct(Backend& backend, const Volume& hu, const RegistrationOptions& options, const Volume* mask);

// The settings a PreparedCt depends on (iso-value, soft-tissue threshold, attenuation of water,
// mesh parameters, each stage's sigma and grid, whether a mask made the bone): a prepared file
// records them, and a registration with other settings must not use it.
nlohmann::json preparation_settings(const RegistrationOptions& options, bool mask);

}  // namespace fluoro
