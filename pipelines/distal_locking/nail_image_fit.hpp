#pragma once
// The X-ray of the nail near its holes as a function of its pose, and the pose that best explains
// an image: every pixel's ray through a metal cylinder with cylindrical holes (exact chords,
// engine/nail_chord.hpp), its transmission blurred by a Gaussian (the detector's and the focal
// spot's blur, before the log), a smooth background per hole window and one common contrast solved
// in closed form at each evaluation (variable projection); Levenberg-Marquardt (Eigen's, numerical
// Jacobian) over the pose, and optionally the blur and the nail's attenuation.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "engine/distal_locking_models.hpp"
#include "engine/image.hpp"
#include "pipelines/calibration/dark_circle_detector.hpp"
#include "pipelines/distal_locking/pose_refinement.hpp"

namespace fluoro {

// Blur (Gaussian sigma, pixels) and the nail's attenuation per mm in the image's line-integral units.
// The fitted attenuation's bounds (per mm, line-integral units).
constexpr double kMinNailAttenuationPerMm = 0.005, kMaxNailAttenuationPerMm = 3.0;

struct NailImaging {
  double blur_px = 0.7;
  double attenuation_per_mm = 0.2;
};

struct NailFitData;

class NailImageModel {
 public:
  // Windows around the holes as projected by `around`: along the nail 1.5 band widths, across
  // 1.24 (a little past the silhouette: further out the bone's inner wall, whose profile no
  // low-order background follows, would bias the fit). Pixels within `occluders` are left out.
  NailImageModel(const Image& xray, const NailModel& nail, const Eigen::Matrix3d& K, const CameraPose& around,
                 double band_width_px, const std::vector<DarkCircle>& occluders);
  ~NailImageModel();
  bool usable() const;  // enough pixels around every hole
  int residual_count() const;  // pixels in use

  // Rays for poses near `pose`: single rays per pixel (coarse), or 16 (9 for a band wider than
  // 30 px) where an edge of the nail's image is within 2 pixels. Fixed during a fit so that the
  // cost stays a smooth function of the pose.
  void set_rays(const CameraPose& pose, bool coarse);
  // RMS residual (image units) of a pose.
  double rms(const CameraPose& pose, const NailImaging& imaging) const;
  // Levenberg-Marquardt from `from`; with `free_imaging` the blur and attenuation are fitted too.
  CameraPose fit(const CameraPose& from, NailImaging* imaging, bool free_imaging, double* rms, int* evaluations);
  // Leaves out what the model cannot explain (a sphere or a wire over a hole that no detection
  // reported): residuals beyond 4 robust sigmas at `pose`, and their 8 neighbours.
  void trim(const CameraPose& pose, const NailImaging& imaging);

 private:
  std::shared_ptr<NailFitData> data_;
};

}  // namespace fluoro
