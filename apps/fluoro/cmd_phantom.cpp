// fluoro phantom: write a deterministic synthetic CT phantom.
#include <cstdio>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "datasets/phantom.hpp"
#include "engine/error.hpp"
#include "engine/json_io.hpp"
#include "engine/volume_io.hpp"

namespace fluoro::cli {
namespace {

struct PhantomOptions {
  std::string kind = "femur", out, fiducials_json;
  int size = 128;
  double fov_mm = 256;
  uint64_t seed = 1;
  bool fiducials = false, metal = false;
};

void run(const PhantomOptions& o) {
  if (o.size < 16 || o.size > 1024) throw_input_error("--size " + std::to_string(o.size), "must be 16 to 1024");
  if (!(o.fov_mm > 0)) throw_input_error("--fov", "must be positive");
  PhantomParams p;
  p.kind = parse_phantom_kind(o.kind);
  p.size = o.size;
  p.fov_mm = o.fov_mm;
  p.seed = o.seed;
  p.fiducials = o.fiducials || !o.fiducials_json.empty();
  p.metal_object = o.metal;
  const Phantom ph = make_phantom(p);
  write_volume(ph.hu, o.out);
  std::printf("wrote %s (%s, %d^3 voxels of %.4g mm)\n", o.out.c_str(), o.kind.c_str(), o.size,
              ph.hu.geometry.spacing.x());
  if (!o.fiducials_json.empty()) {
    nlohmann::json j;
    j["radius_mm"] = ph.fiducial_radius_mm;
    j["centres_mm"] = nlohmann::json::array();
    for (const auto& c : ph.fiducials) j["centres_mm"].push_back({c.x(), c.y(), c.z()});
    write_json(j, o.fiducials_json);
    std::printf("wrote %s (%zu fiducials, CT frame)\n", o.fiducials_json.c_str(), ph.fiducials.size());
  }
}

}  // namespace

void add_phantom_command(CLI::App& app) {
  auto o = std::make_shared<PhantomOptions>();
  auto* cmd = app.add_subcommand("phantom", "Write a synthetic CT phantom (HU) of a long bone, a pelvis or a head");
  cmd->add_option("--kind", o->kind, "femur | pelvis | head")->capture_default_str();
  cmd->add_option("--size", o->size, "Voxels per side")->capture_default_str();
  cmd->add_option("--fov", o->fov_mm, "Side of the cubic field of view, mm")->capture_default_str();
  cmd->add_option("--seed", o->seed, "Seed of the shape variations")->capture_default_str();
  cmd->add_flag("--fiducials", o->fiducials, "Implant fiducial spheres");
  cmd->add_option("--fiducials-json", o->fiducials_json, "Write the fiducial centres here (implies --fiducials)");
  cmd->add_flag("--metal", o->metal, "Add a foreign metal object");
  cmd->add_option("--out", o->out, "Output volume (.nii, .nii.gz, .mha, .nrrd)")->required();
  cmd->callback([o] { run(*o); });
}

}  // namespace fluoro::cli
