// Camera calibration at 1024^2 (issue 10): the time of `fluoro calibrate`'s work (detection of
// the balls, pairing, DLT, Levenberg-Marquardt) on generated phantom X-rays, and the accuracy
// side by side with OpenCV on the same detections.
// Counters: mean_px / max_px, the reprojection gap against the true camera over a 10^3 grid
// through the phantom's bounding box; for the comparison, the mean over the seeds of each
// method's mean gap (ours, our DLT alone, cv::calibrateCamera from our DLT's K, cv::solvePnP
// given the true K).
#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <opencv2/calib3d.hpp>
#include <string>

#include "datasets/calibration_phantom.hpp"
#include "pipelines/calibration/camera_calibration.hpp"
#include "pipelines/calibration/dark_circle_detector.hpp"
#include "pipelines/calibration/volume_reprojection.hpp"

namespace fluoro {
namespace {

// The C-arm: 1024^2 pixels of 0.38 mm, 1000 mm from source to detector; the phantom on
// the intensifier, turned and tilted a little ("axial") or tilted by 15 degrees ("oblique").
PhantomView view_1024(bool oblique) {
  PhantomView v;
  v.axis_turn_deg = 17;
  v.tilt_deg = oblique ? 15 : 4;
  v.tilt_azimuth_deg = 30;
  v.shift_mm = Eigen::Vector2d(6, -4);
  v.principal_offset_px = Eigen::Vector2d(7, -4.5);
  return v;
}

XrayRendering rendering(bool noisy, uint64_t seed) {
  XrayRendering r;
  r.seed = seed;
  if (noisy) {
    r.blur_sigma_px = 0.7;
    r.photons_per_pixel = 150;
    r.clutter_balls = 3;
    r.clutter_wires = 1;
  }
  return r;
}

// The X-ray as the CLI reads it from the 16-bit log-domain PNG.
Image xray_of(const CalibrationScene& scene) {
  Image img(scene.line_integral.width, scene.line_integral.height);
  const auto png = log_domain_png_pixels(scene.line_integral);
  for (size_t i = 0; i < png.size(); ++i) img.pixels[i] = float(png[i]);
  return img;
}

void bounds(const PhantomModel& p, Eigen::Vector3d* lo, Eigen::Vector3d* hi) {
  *lo = *hi = p.fiducials[0].position_mm;
  for (const auto& f : p.fiducials) *lo = lo->cwiseMin(f.position_mm), *hi = hi->cwiseMax(f.position_mm);
}

PhantomModel phantom_named(int which) { return which == 0 ? tower_phantom() : ring_phantom(); }

CameraCalibration calibrate_image(const PhantomModel& phantom, const Image& img) {
  std::vector<DetectedCentre> centres;
  for (const auto& c : detect_dark_circles(img)) centres.push_back({c.centre_px, c.crowded});
  return calibrate_camera(phantom, centres, img.width, img.height);
}

// Args: phantom (0 tower, 1 ring), noisy (0/1), oblique (0/1).
void BM_Calibrate1024(benchmark::State& state) {
  const PhantomModel phantom = phantom_named(int(state.range(0)));
  const CalibrationScene scene =
      render_calibration_scene(phantom, view_1024(state.range(2) != 0), rendering(state.range(1) != 0, 1));
  const Image img = xray_of(scene);
  CameraCalibration cal;
  for (auto _ : state) {
    cal = calibrate_image(phantom, img);
    benchmark::DoNotOptimize(cal.rms_px);
  }
  if (!cal.ok) {
    state.SkipWithError(cal.failure_reason.c_str());
    return;
  }
  Eigen::Vector3d lo, hi;
  bounds(phantom, &lo, &hi);
  const ReprojectionGap g = volume_reprojection_gap(cal.camera, scene.camera, lo, hi);
  state.counters["mean_px"] = g.mean_px;
  state.counters["max_px"] = g.max_px;
  state.counters["source_err_mm"] = (cal.camera.source() - scene.camera.source()).norm();
  state.counters["paired"] = double(cal.fiducials.size());
}
BENCHMARK(BM_Calibrate1024)
    ->ArgsProduct({{0, 1}, {0, 1}, {0, 1}})
    ->ArgNames({"ring", "noisy", "oblique"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The detector alone (the Hough transform, verification and centroids) on the same images.
void BM_DetectBalls1024(benchmark::State& state) {
  const PhantomModel phantom = phantom_named(int(state.range(0)));
  const Image img = xray_of(render_calibration_scene(phantom, view_1024(false), rendering(state.range(1) != 0, 1)));
  size_t found = 0;
  for (auto _ : state) {
    found = detect_dark_circles(img).size();
    benchmark::DoNotOptimize(found);
  }
  state.counters["found"] = double(found);
}
BENCHMARK(BM_DetectBalls1024)
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->ArgNames({"ring", "noisy"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

PinholeCamera from_opencv(const cv::Matx33d& K, const cv::Mat& rvec, const cv::Mat& tvec, int w, int h) {
  PinholeCamera c;
  c.width = w;
  c.height = h;
  cv::Matx33d R;
  cv::Rodrigues(rvec, R);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) c.K(i, j) = K(i, j), c.R(i, j) = R(i, j);
    c.t(i) = tvec.at<double>(i);
  }
  return c;
}

// The same detections and pairs for every method; seeds 1..8 of the noise (one image if clean).
// Args: phantom (0 tower, 1 ring), noisy (0/1), oblique (0/1).
void BM_CompareWithOpenCV(benchmark::State& state) {
  const PhantomModel phantom = phantom_named(int(state.range(0)));
  const bool noisy = state.range(1) != 0;
  const int seeds = noisy ? 8 : 1;
  Eigen::Vector3d lo, hi;
  bounds(phantom, &lo, &hi);
  std::map<std::string, double> mean, worst;
  for (auto _ : state) {
    mean.clear();
    worst.clear();
    for (int seed = 1; seed <= seeds; ++seed) {
      const CalibrationScene scene =
          render_calibration_scene(phantom, view_1024(state.range(2) != 0), rendering(noisy, uint64_t(seed)));
      const Image img = xray_of(scene);
      const CameraCalibration cal = calibrate_image(phantom, img);
      if (!cal.ok) {
        state.SkipWithError(cal.failure_reason.c_str());
        return;
      }
      std::vector<cv::Point3f> obj;
      std::vector<cv::Point2f> pix;
      for (const auto& f : cal.fiducials) {
        if (f.outlier) continue;
        const Eigen::Vector3d& X = phantom.fiducials[size_t(f.fiducial)].position_mm;
        obj.emplace_back(float(X.x()), float(X.y()), float(X.z()));
        pix.emplace_back(float(f.pixel.x()), float(f.pixel.y()));
      }
      // calibrateCamera: non-planar points need CALIB_USE_INTRINSIC_GUESS; the guess is our DLT's
      // K; distortion is held at zero like ours (a dewarp removes it beforehand).
      cv::Matx33d K;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) K(i, j) = cal.dlt_camera.K(i, j);
      K(0, 1) = 0;
      cv::Mat dist = cv::Mat::zeros(5, 1, CV_64F);
      std::vector<cv::Mat> rvecs, tvecs;
      cv::calibrateCamera(std::vector<std::vector<cv::Point3f>>{obj}, std::vector<std::vector<cv::Point2f>>{pix},
                          cv::Size(img.width, img.height), K, dist, rvecs, tvecs,
                          cv::CALIB_USE_INTRINSIC_GUESS | cv::CALIB_ZERO_TANGENT_DIST | cv::CALIB_FIX_K1 |
                              cv::CALIB_FIX_K2 | cv::CALIB_FIX_K3,
                          cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 200, 1e-12));
      const PinholeCamera cv_cal = from_opencv(K, rvecs[0], tvecs[0], img.width, img.height);
      // solvePnP given the true K: the pose alone, the best a pose-only method can do.
      cv::Matx33d Kt;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) Kt(i, j) = scene.camera.K(i, j);
      cv::Mat rvec, tvec;
      cv::solvePnP(obj, pix, Kt, cv::noArray(), rvec, tvec, false, cv::SOLVEPNP_ITERATIVE);
      const PinholeCamera cv_pnp = from_opencv(Kt, rvec, tvec, img.width, img.height);

      const std::pair<const char*, const PinholeCamera*> methods[] = {
          {"ours", &cal.camera}, {"dlt", &cal.dlt_camera}, {"cv_calibrate", &cv_cal}, {"cv_pnp_trueK", &cv_pnp}};
      for (const auto& [name, cam] : methods) {
        const ReprojectionGap g = volume_reprojection_gap(*cam, scene.camera, lo, hi);
        mean[name] += g.mean_px / seeds;
        worst[name] = std::max(worst[name], g.max_px);
      }
    }
  }
  for (const auto& [name, v] : mean) {
    state.counters[name + "_mean_px"] = v;
    state.counters[name + "_max_px"] = worst[name];
  }
}
BENCHMARK(BM_CompareWithOpenCV)
    ->ArgsProduct({{0, 1}, {0, 1}, {0, 1}})
    ->ArgNames({"ring", "noisy", "oblique"})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

}  // namespace
}  // namespace fluoro

BENCHMARK_MAIN();
