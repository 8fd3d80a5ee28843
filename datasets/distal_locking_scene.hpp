#pragma once
// Distal-locking X-rays with known truth (the seed's chapter 4): a robot-mounted drill guide of 28
// steel spheres on two planes, an intramedullary nail (a metal cylinder with two cylindrical
// through-holes), the bone tube around it, soft tissue, the calibration ring's balls as clutter,
// blur and quantum noise; exact per-pixel line integrals, supersampled over each pixel.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "engine/camera.hpp"
#include "engine/distal_locking_models.hpp"
#include "engine/image.hpp"

namespace fluoro {

// Our drill guide: 28 spheres of 3 mm, 14 on the plane z = 0 and 14 on z = 20 mm, at fixed
// irregular places (no symmetry maps the set onto itself), at least 7 mm apart and 6 mm clear of
// the two drill axes, which run along z through (-15, 0) and (15, 0): the guide's z points from the
// guide towards the nail.
DrillGuideModel drill_guide_model();
// A 10 mm nail with two 5 mm holes 30 mm apart (x = -15 and 15).
NailModel nail_model();

// The view: where the nail, the guide and the C-arm are.
struct DistalView {
  int pixels = 512;                   // square detector
  double detector_mm = 300;           // its side: pixel size = detector_mm / pixels
  double source_to_detector_mm = 1000;
  double nail_depth_mm = 700;         // source to the nail's centre
  double nail_roll_deg = 20;          // the nail's long axis in the image, from the image's u axis
  double tilt_deg = 0;                // angle between the hole axes and the ray through the nail's centre
  double tilt_azimuth_deg = 30;       // about which in-plane direction the nail tilts (0 = about its long axis)
  Eigen::Vector2d nail_offset_mm = Eigen::Vector2d(4, -3);  // nail centre off the central ray, lateral
  double guide_gap_mm = 35;           // nail surface to the guide's near sphere plane, along the hole axes
  double guide_misalignment_deg = 3;  // angle between the guide axes and the hole axes
  Eigen::Vector3d guide_offset_mm = Eigen::Vector3d(3, -2, 0);  // guide axes' midpoint off the holes', nail frame
  Eigen::Vector2d principal_offset_px = Eigen::Vector2d(3.0, -2.0);
};

struct DistalRendering {
  double steel_mu_per_mm = 0.6;        // guide spheres and ring balls
  double nail_mu_per_mm = 0.2;         // the nail (titanium alloy, effective)
  double bone_mu_per_mm = 0.04;        // cortical tube, 8-14 mm radius, around the nail
  double tissue_mu_per_mm = 0.02;      // soft tissue cylinder around the bone
  double tissue_radius_mm = 40;
  bool nail_present = true;            // false: bone and tissue only (a view that missed the nail)
  bool ring_clutter = true;            // the calibration ring's 26 balls near the detector
  int hidden_spheres = 0;              // guide spheres left out (occluded or not detected)
  int supersampling = 3;               // rays per pixel side
  double blur_sigma_px = 0.0;
  double photons_per_pixel = 0.0;      // 0 = no quantum noise
  uint64_t seed = 1;
};

// A scene with its truth. The world frame is the camera file's: the camera sits at a fixed,
// non-trivial pose in it, so that frame conversions are exercised.
struct DistalScene {
  PinholeCamera camera;
  DrillGuideModel guide;
  NailModel nail;
  Eigen::Isometry3d T_world_guide, T_world_nail;
  std::vector<int> hidden_ids;         // guide spheres left out of the image
  Image line_integral;                 // -ln(I / I0) per pixel after blur and noise
};

DistalScene render_distal_scene(const DistalView& view, const DistalRendering& rendering);

// Writes `<prefix>.png` (16-bit log domain, as fluoro distal-lock reads it), `<prefix>_camera.json`,
// `<prefix>_guide.json`, `<prefix>_nail.json` and `<prefix>_truth.json` (T_world_guide, T_world_nail).
void write_distal_scene(const DistalScene& scene, const std::string& prefix);

}  // namespace fluoro
