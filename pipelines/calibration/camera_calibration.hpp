#pragma once
// Camera calibration from one X-ray of a fiducial phantom: pair the detected ball centres with the
// phantom's fiducials, a normalised DLT for P, its RQ decomposition into K, R, t, then
// Levenberg-Marquardt on the reprojection error over the intrinsics and the pose.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "engine/camera.hpp"
#include "engine/phantom_model.hpp"
#include "pipelines/calibration/fiducial_matching.hpp"

namespace fluoro {

// A ball centre in the camera's pixel frame (after a dewarp, when there is one). A crowded
// centre (another blob in its window) helps the pairing but is left out of the fit.
struct DetectedCentre {
  Eigen::Vector2d pixel;
  bool crowded = false;
};

// Knobs of the calibration; the defaults are what the CLI uses.
// Residuals above max(outlier_factor * robust sigma, outlier_floor_px) are dropped once and refitted.
struct CalibrationParams {
  MatchingParams matching;
  double outlier_factor = 5.0;
  double outlier_floor_px = 0.05;
};

// A fiducial used in the fit: its index in the phantom, its detection, the observed and the
// reprojected pixel, and the distance of the ray through the observed pixel from the model point.
struct CalibratedFiducial {
  int fiducial = -1;
  int detection = -1;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero(), reprojected = Eigen::Vector2d::Zero();
  double residual_px = 0;
  double backprojection_mm = 0;
  bool outlier = false;   // paired, but left out of the final fit
};

// The outcome. `camera` is meaningful only when ok; otherwise `failure_reason` says why (too few
// balls, degenerate geometry) and no camera is to be written.
struct CameraCalibration {
  bool ok = false;
  std::string failure_reason;
  PinholeCamera camera;
  PinholeCamera dlt_camera;        // the DLT's decomposition, before refinement
  std::vector<CalibratedFiducial> fiducials;
  double rms_px = 0, max_px = 0;   // over the fiducials in the fit
  int lm_evaluations = 0;
};

// Calibrates the camera of a width x height image whose world frame is the phantom's frame.
CameraCalibration calibrate_camera(const PhantomModel& phantom, const std::vector<DetectedCentre>& centres,
                                   int width, int height, const CalibrationParams& params = {});

// Several images of the phantom at one C-arm orientation (the phantom moved between them): each
// is paired and calibrated alone, then the images calibrated successfully share one K in a joint
// refinement (their own poses). One result per image, in order; a failed image keeps its reason.
std::vector<CameraCalibration> calibrate_camera_views(const PhantomModel& phantom,
                                                     const std::vector<std::vector<DetectedCentre>>& images,
                                                     int width, int height, const CalibrationParams& params = {});

// Distance of the ray from the camera's source through `pixel` from the world point `x`.
double ray_point_distance(const PinholeCamera& camera, const Eigen::Vector2d& pixel, const Eigen::Vector3d& x);

}  // namespace fluoro
