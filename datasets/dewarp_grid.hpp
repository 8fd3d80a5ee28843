#pragma once
// Synthetic dewarp-grid X-rays: the seed's aluminium hole plate on the image intensifier, seen
// through a known image-intensifier distortion, with blur, noise, occluders and dust; truth kept.
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "engine/grid_model.hpp"
#include "engine/image.hpp"

namespace fluoro {

// The true image-intensifier distortion: pincushion (k1 r^2 + k2 r^4), a swirl (rotation growing as
// r^2), Brown decentring (p1, p2) about a shifted centre. Maps ideal pixels <-> distorted pixels.
struct IIDistortion {
  Eigen::Vector2d centre_px{0, 0};  // centre of distortion (pixels)
  double radius_px = 512;           // normalising radius
  double k1 = 0, k2 = 0, swirl = 0, p1 = 0, p2 = 0;

  // Ideal (pinhole) pixel -> distorted pixel, as the image intensifier bends it.
  Eigen::Vector2d distort(const Eigen::Vector2d& ideal) const;
  // Distorted pixel -> ideal pixel (Newton on distort(), to 1e-10 px); `guess` speeds it up.
  Eigen::Vector2d undistort(const Eigen::Vector2d& distorted) const;
  Eigen::Vector2d undistort(const Eigen::Vector2d& distorted, const Eigen::Vector2d& guess) const;
};

// What to render: the image and detector, the plate (GRID.json), the distortion's strength and the
// C-arm orientation it depends on, and the nuisances (blur, noise, an occluder, dust).
struct DewarpSceneOptions {
  int size = 1024;                   // square image, pixels
  uint64_t seed = 1;                 // varies the plate's placement, the occluder and the dust
  double orbit_deg = 0;              // C-arm orientation: the distortion depends on it
  double edge_displacement_px = 12;  // distortion at the FOV edge, for a 1024 image (scaled with size)
  double pixel_mm = 0.38;            // detector pixel at 1024 (scaled by 1024 / size)
  double source_to_detector_mm = 1000;
  double plate_to_detector_mm = 40;  // plate mid-plane above the detector (magnification ~1.04)
  double fov_radius = 0.47;          // circular field of view, fraction of the image size
  double blur_sigma_px = 0.8;        // Gaussian blur (at 1024, scaled with size)
  double noise_sigma = 0.0;          // Gaussian noise, as a fraction of the holes' contrast
  double hidden_fraction = 0.0;      // fraction of the FOV's holes a dense metal bar hides
  int dust_count = 0;                // small spurious blobs, bright and dark
  int supersampling = 4;             // per axis, for partial-volume coverage
  GridModel grid{10.0, 3.0, 45, 45, 7.0};
};

// One hole of the plate that lies inside the image's field of view: its lattice index and where it
// projects without and with the distortion.
struct DewarpTruthHole {
  int row = 0, col = 0;
  Eigen::Vector2d ideal_px, distorted_px;
  bool visible = true;  // false when an occluder or the FOV edge touches it
};

// A generated grid X-ray and its ground truth: the distortion, the plate -> ideal-pixel similarity
// and every hole inside the field of view with its visibility.
struct DewarpScene {
  Image image;  // log-domain, values in [0, 65535] (holes bright), 0 outside the circular FOV
  GridModel grid;
  IIDistortion distortion;
  Eigen::Vector2d plate_origin_px;  // ideal pixel of plate point (0, 0) mm
  Eigen::Matrix2d plate_to_ideal;   // ideal_px = plate_origin_px + plate_to_ideal * plate_mm
  Eigen::Vector2d fov_centre_px;
  double fov_radius_px = 0;
  std::vector<DewarpTruthHole> holes;
  double hidden_fraction = 0;  // achieved: hidden holes / holes inside the FOV

  Eigen::Vector2d ideal_of_plate(const Eigen::Vector2d& plate_mm) const {
    return plate_origin_px + plate_to_ideal * plate_mm;
  }
  // Plate point -> where it appears in the distorted image.
  Eigen::Vector2d distorted_of_plate(const Eigen::Vector2d& plate_mm) const {
    return distortion.distort(ideal_of_plate(plate_mm));
  }
  double px_per_plate_mm() const { return std::sqrt(std::abs(plate_to_ideal.determinant())); }
};

// Mean and largest error of a map, plate millimetres, over `samples` points.
struct DewarpErrorStats {
  double mean_mm = 0, max_mm = 0;
  int samples = 0;
};
// between: points inside lattice cells whose four corner holes are visible (the goals' points);
// elsewhere: the rest of the map's field of view (under an occluder, outside the last holes).
struct DewarpMapError {
  DewarpErrorStats between, elsewhere;
};

// The residual metric of docs/calibration.md: 16 points per lattice cell (cell centres included)
// taken through the truth's distortion, then through `correct` (distorted -> corrected pixels;
// nullopt outside its field of view); the best similarity from corrected to ideal pixels, fitted
// on the visible hole centres, removes the frame the map was free to choose.
DewarpMapError dewarp_map_error(const DewarpScene& scene,
                                const std::function<std::optional<Eigen::Vector2d>(const Eigen::Vector2d&)>& correct);

// An ideal (pinhole) image as the image intensifier bends it: each distorted pixel shows the ideal
// image at its undistorted position (bilinear, cv::remap through the exact inverse). Used to put
// any generated X-ray (a phantom, a panorama frame) through a grid scene's distortion.
Image distort_image(const Image& ideal, const IIDistortion& distortion);

// Renders the scene (deterministic for given options). Throws std::invalid_argument on options
// out of range.
DewarpScene make_dewarp_scene(const DewarpSceneOptions& options);

// Writes the image as a 16-bit PNG and the plate as GRID.json (atomic writes).
void save_dewarp_scene(const DewarpScene& scene, const std::string& image_path, const std::string& grid_path);

}  // namespace fluoro
