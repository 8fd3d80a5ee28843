#pragma once
// Deterministic synthetic CT phantoms (HU), generated in-process: the same parameters give the
// same voxels on every machine. Used by the demo, the tests and the benchmarks.
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "engine/volume.hpp"

namespace fluoro {

// femur: a right femur in the thigh; pelvis: the pelvic ring with both proximal femurs; head: a
// skull (a thin cortical shell, 2 to 7 mm, around the brain, the face with its air sinuses, a jaw).
enum class PhantomKind { femur, pelvis, head };

struct PhantomParams {
  PhantomKind kind = PhantomKind::femur;
  int size = 128;             // voxels per side (64 to 256 typical); the field of view is fixed
  double fov_mm = 256.0;      // physical side length of the cubic volume
  uint64_t seed = 1;          // drives the small random shape variations
  bool fiducials = false;     // implant a few metal-free ceramic spheres (high HU) near the bone
  bool metal_object = false;  // a foreign metal object (a screw-like rod), 3000 HU
};

struct Phantom {
  Volume hu;                                 // Hounsfield units, identity direction, centred on 0
  std::vector<Eigen::Vector3d> fiducials;    // sphere centres (CT physical frame, mm), if any
  double fiducial_radius_mm = 0.0;
};

// Tissue values: cortical bone ~1500 HU, marrow (and the skull's diploe) ~300 HU, soft tissue
// (and brain) ~40 HU, air (outside, and the head's sinuses) -1000 HU.
Phantom make_phantom(const PhantomParams& params);

PhantomKind parse_phantom_kind(const std::string& name);  // "femur" | "pelvis" | "head"; InputError otherwise

}  // namespace fluoro
