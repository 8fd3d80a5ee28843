#include "pipelines/calibration/camera_calibration.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "engine/error.hpp"
#include "pipelines/calibration/camera_refinement.hpp"
#include "pipelines/calibration/projection_dlt.hpp"

namespace fluoro {
namespace {

// Smallest over largest eigenvalue of the points' scatter: 0 for points in a lower dimension.
template <int D>
double flatness(const std::vector<Eigen::Matrix<double, D, 1>>& pts) {
  Eigen::Matrix<double, D, 1> mean = Eigen::Matrix<double, D, 1>::Zero();
  for (const auto& p : pts) mean += p;
  mean /= double(pts.size());
  Eigen::Matrix<double, D, D> s = Eigen::Matrix<double, D, D>::Zero();
  for (const auto& p : pts) s += (p - mean) * (p - mean).transpose();
  const auto ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, D, D>>(s).eigenvalues();
  return ev(D - 1) > 0 ? ev(0) / ev(D - 1) : 0.0;
}

// The fit's rms and max over the fiducials it used.
void summarise(CameraCalibration& r) {
  double ss = 0;
  int n = 0;
  r.max_px = 0;
  for (const auto& f : r.fiducials) {
    if (f.outlier) continue;
    ss += f.residual_px * f.residual_px;
    r.max_px = std::max(r.max_px, f.residual_px);
    ++n;
  }
  r.rms_px = std::sqrt(ss / n);
}

CameraCalibration failed(CameraCalibration r, const std::string& why) {
  r.ok = false;
  r.failure_reason = why;
  return r;
}

}  // namespace

double ray_point_distance(const PinholeCamera& camera, const Eigen::Vector2d& pixel, const Eigen::Vector3d& x) {
  const Eigen::Vector3d d = camera.ray_direction(pixel.x(), pixel.y());
  return (x - camera.source()).cross(d).norm();
}

CameraCalibration calibrate_camera(const PhantomModel& phantom, const std::vector<DetectedCentre>& centres,
                                   int width, int height, const CalibrationParams& params) {
  CameraCalibration r;
  if (centres.size() < 6)
    return failed(r, "only " + std::to_string(centres.size()) + " balls found in the image; 6 are needed");
  std::vector<Eigen::Vector3d> model;
  for (const auto& f : phantom.fiducials) model.push_back(f.position_mm);
  std::vector<Eigen::Vector2d> pixels;
  for (const auto& c : centres) pixels.push_back(c.pixel);

  MatchingDiagnostics diag;
  const auto match = match_fiducials(model, pixels, width, height, params.matching, &diag);
  if (!match && diag.coplanar_pairs_seen)
    return failed(r, "the balls found pair only with coplanar fiducials: one image of them cannot calibrate a camera");
  if (!match)
    return failed(r, "fewer than 6 of the " + std::to_string(centres.size()) +
                         " balls found match the phantom's pattern");
  for (size_t i = 0; i < model.size(); ++i) {
    const int d = match->detection_of[i];
    if (d < 0 || centres[size_t(d)].crowded) continue;
    CalibratedFiducial f;
    f.fiducial = int(i);
    f.detection = d;
    f.pixel = pixels[size_t(d)];
    r.fiducials.push_back(f);
  }
  if (r.fiducials.size() < 6)
    return failed(r, "only " + std::to_string(r.fiducials.size()) +
                         " balls matched the phantom clear of other blobs; 6 are needed");

  auto fit = [&](bool drop_outliers) -> std::string {
    std::vector<Eigen::Vector3d> X;
    std::vector<Eigen::Vector2d> x;
    for (const auto& f : r.fiducials)
      if (!(drop_outliers && f.outlier)) X.push_back(model[size_t(f.fiducial)]), x.push_back(f.pixel);
    if (X.size() < 6) return "only " + std::to_string(X.size()) + " consistent balls; 6 are needed";
    // One image of coplanar points leaves the camera undetermined (a homography has 8 degrees of
    // freedom, the camera 10); collinear pixels mean a degenerate view.
    if (flatness<3>(X) < 1e-6) return "the matched fiducials are coplanar: one image of them cannot calibrate a camera";
    if (flatness<2>(x) < 1e-6) return "the matched ball centres are collinear in the image";
    const auto P = projection_dlt(X, x);
    if (!P) return "the DLT is degenerate for the matched fiducials";
    try {
      r.dlt_camera = camera_from_projection(*P, width, height, "DLT");
    } catch (const InputError& e) {
      return std::string("the DLT's projection cannot be decomposed (") + e.what() + ")";
    }
    r.camera = refine_camera(r.dlt_camera, X, x, &r.lm_evaluations);
    return "";
  };
  if (const std::string why = fit(false); !why.empty()) return failed(r, why);

  auto measure = [&] {
    std::vector<double> res;
    for (auto& f : r.fiducials) {
      f.reprojected = r.camera.project(model[size_t(f.fiducial)]);
      f.residual_px = (f.reprojected - f.pixel).norm();
      f.backprojection_mm = ray_point_distance(r.camera, f.pixel, model[size_t(f.fiducial)]);
      res.push_back(f.residual_px);
    }
    return res;
  };
  // One round of outlier rejection: a ball whose centre a wire or a clutter ball pulled.
  std::vector<double> res = measure();
  std::vector<double> sorted = res;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double limit = std::max(params.outlier_factor * 1.4826 * sorted[sorted.size() / 2], params.outlier_floor_px);
  int kept = 0;
  for (auto& f : r.fiducials) kept += (f.outlier = f.residual_px > limit) ? 0 : 1;
  if (kept >= 6 && kept < int(r.fiducials.size())) {
    if (const std::string why = fit(true); !why.empty()) return failed(r, why);
    res = measure();
  } else {
    for (auto& f : r.fiducials) f.outlier = false;
  }
  summarise(r);
  if (!std::isfinite(r.rms_px)) return failed(r, "a matched fiducial lies behind the estimated source");
  if (!r.camera.K.allFinite() || !(r.camera.K(0, 0) > 0) || !(r.camera.K(1, 1) > 0) || !r.camera.t.allFinite())
    return failed(r, "the refinement diverged");
  r.ok = true;
  return r;
}

std::vector<CameraCalibration> calibrate_camera_views(const PhantomModel& phantom,
                                                     const std::vector<std::vector<DetectedCentre>>& images,
                                                     int width, int height, const CalibrationParams& params) {
  std::vector<CameraCalibration> out;
  std::vector<RefinementView> views;
  std::vector<size_t> joined;
  for (size_t k = 0; k < images.size(); ++k) {
    out.push_back(calibrate_camera(phantom, images[k], width, height, params));
    if (!out.back().ok) continue;
    RefinementView v;
    v.start = out.back().camera;
    for (const auto& f : out.back().fiducials)
      if (!f.outlier) v.points.push_back(phantom.fiducials[size_t(f.fiducial)].position_mm), v.pixels.push_back(f.pixel);
    views.push_back(std::move(v));
    joined.push_back(k);
  }
  if (views.size() < 2) return out;
  const std::vector<PinholeCamera> cams = refine_cameras_shared_intrinsics(views);
  for (size_t j = 0; j < joined.size(); ++j) {
    CameraCalibration& r = out[joined[j]];
    r.camera = cams[j];
    for (auto& f : r.fiducials) {
      const Eigen::Vector3d& X = phantom.fiducials[size_t(f.fiducial)].position_mm;
      f.reprojected = r.camera.project(X);
      f.residual_px = (f.reprojected - f.pixel).norm();
      f.backprojection_mm = ray_point_distance(r.camera, f.pixel, X);
    }
    summarise(r);
  }
  return out;
}

}  // namespace fluoro
