#pragma once
// Synthetic long-bone panorama sets with ground truth: a femur-like bone on a soft-tissue
// cylinder, an orthopaedic ruler on the table at another height, foreign objects, and a C-arm
// translated along the bone (fronto-parallel views). Analytic line integrals, 16-bit log domain.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "engine/camera.hpp"
#include "engine/image.hpp"

namespace fluoro {

// What to generate. World frame: the sources lie in the plane z = 0 and look along +z; the bone's
// axis runs along world x in the plane z = bone_plane_mm; the ruler lies in z = bone_plane_mm +
// ruler_offset_mm (negative: nearer the source, as on a table above an under-table source).
struct PanoramaSceneParams {
  int pixels = 512;                 // square images
  double detector_mm = 230;         // detector width (image-intensifier field)
  double source_to_detector_mm = 1000;
  double bone_plane_mm = 700;       // source to the bone's apparent-contour plane
  double ruler_offset_mm = -50;     // ruler plane minus bone plane (0: same plane, no parallax)
  double landmark_distance_mm = 380;
  int frames = 6;
  double overlap = 0.4;             // fraction of the field of view shared by consecutive frames
  double max_rotation_deg = 5;      // in-plane rotation of each frame, uniform in +-max
  double lateral_jitter_mm = 4;     // C-arm position across the bone, uniform in +-jitter
  double along_jitter_mm = 4;       // C-arm position along the bone, uniform in +-jitter
  double ruler_angle_deg = 1.5;     // ruler direction relative to the bone axis
  double graduation_mm = 5;
  double blur_px = 0.8;             // Gaussian sigma, pixels (at 512 px; scaled with `pixels`)
  double noise = 150;               // Gaussian sigma, 16-bit grey levels
  bool occluders = true;            // k-wires across the ruler and a clamp hiding graduations
  int gap_after_frame = -1;         // >= 0: frame gap_after_frame + 1 starts past the previous one's field
  uint32_t seed = 1;
};

// One generated set with its truth.
struct PanoramaScene {
  std::vector<ImageU16> images;
  std::vector<PinholeCamera> cameras;  // true cameras (K shared, R about the optical axis)
  std::vector<double> rotation_deg;    // in-plane rotation of each frame (camera about +z)
  Eigen::Vector3d landmarks[2];        // bone landmarks, in the bone plane (world mm)
  double true_length_mm = 0;           // distance between the landmarks
  double bone_plane_mm = 0, ruler_plane_mm = 0;
  double focal_px = 0;
  // A bone outline traced on two consecutive frames (C.json of FORMATS.md), in the images' pixels.
  int contour_first_frame = 0;
  std::vector<Eigen::Vector2d> contour[2];
  double clamp_hidden_fraction = 0;    // graduations hidden by the clamp in its worst frame
};

// Renders a set. Deterministic for given parameters (same seed, same images).
PanoramaScene make_panorama_scene(const PanoramaSceneParams& params);

// The pixel of world point x in frame i (true camera).
Eigen::Vector2d project_in_frame(const PanoramaScene& scene, int frame, const Eigen::Vector3d& x);

}  // namespace fluoro
