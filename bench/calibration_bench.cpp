// The calibration pipeline's speed, with its accuracy as counters.
// Distortion correction at 1024^2: `dewarp fit` (hole detection, lattice, both map models) on a
// clean grid and on a noisy one with 35 % of the holes hidden and dust, its accuracy between the
// holes over four C-arm orientations (counters, plate mm), and `dewarp apply` of a 16-bit image
// once the map is loaded (the goal: at most 10 ms), plus the one-off remap tables, and a
// robustness sweep over many noisy scenes with 40 % of the holes hidden.
// Point tools: the Embree index build and closest-point queries (from scratch, and from the
// closest points before a small move) on a 100k-triangle mesh, a whole
// trimmed point-to-plane ICP of 5,000 noisy points with 10 % outliers starting 8 deg / 8 mm off
// (counters: surface TRE, rms, iterations), pivot calibration, and the Fitzpatrick-West
// prediction against a Monte-Carlo estimate (counter: measured / predicted TRE).
//
// Camera calibration at 1024^2 (issue 10): the time of `fluoro calibrate`'s work (detection of
// the balls, pairing, DLT, Levenberg-Marquardt) on generated phantom X-rays, and the accuracy
// side by side with OpenCV on the same detections.
// Counters: mean_px / max_px, the reprojection gap against the true camera over a 10^3 grid
// through the phantom's bounding box; for the comparison, the mean over the seeds of each
// method's mean gap (ours, our DLT alone, cv::calibrateCamera from our DLT's K, cv::solvePnP
// given the true K).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <numbers>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <random>
#include <string>

#include "datasets/calibration_phantom.hpp"
#include "datasets/dewarp_grid.hpp"
#include "datasets/point_tool_scenes.hpp"
#include "engine/random_draws.hpp"
#include "kernels/mesh/closest_point.hpp"
#include "pipelines/calibration/camera_calibration.hpp"
#include "pipelines/calibration/dark_circle_detector.hpp"
#include "pipelines/calibration/dewarp_fit.hpp"
#include "pipelines/calibration/icp.hpp"
#include "pipelines/calibration/pivot_calibration.hpp"
#include "pipelines/calibration/target_registration_error.hpp"
#include "pipelines/calibration/volume_reprojection.hpp"
#include "pipelines/registration/point_registration.hpp"

namespace fluoro {
namespace {

// condition 0: clean (blur only); 1: noise 5 % of the hole contrast, 35 % hidden, 40 dust specks.
const DewarpScene& dewarp_scene(int condition, int orientation) {
  static std::map<std::pair<int, int>, DewarpScene> cache;
  const auto key = std::make_pair(condition, orientation);
  auto it = cache.find(key);
  if (it != cache.end()) return it->second;
  DewarpSceneOptions o;  // 1024^2, 0.38 mm pixels, 12 px of distortion at the FOV's edge
  o.seed = uint64_t(10 + orientation);
  o.orbit_deg = 90.0 * orientation;
  if (condition == 1) o.noise_sigma = 0.05, o.hidden_fraction = 0.35, o.dust_count = 40;
  return cache.emplace(key, make_dewarp_scene(o)).first->second;
}

// Args: model (0 polynomial, 1 bilinear), condition. Timed: the fit of orientation 0. Counters: the
// error between holes (mean of the four orientations' means, largest max) and elsewhere in the FOV.
void BM_DewarpFit(benchmark::State& state) {
  DewarpFitOptions options;
  options.model = state.range(0) == 0 ? DewarpModel::polynomial : DewarpModel::bilinear;
  const int condition = int(state.range(1));
  const DewarpScene& s = dewarp_scene(condition, 0);
  int used = 0;
  for (auto _ : state) {
    const DewarpFit fit = fit_dewarp(s.image, s.grid, options);
    used = fit.holes_used;
    benchmark::DoNotOptimize(fit.ok);
  }
  double mean = 0, max = 0, else_mean = 0, else_max = 0, hidden = 0;
  for (int orientation = 0; orientation < 4; ++orientation) {
    const DewarpScene& sc = dewarp_scene(condition, orientation);
    const DewarpFit fit = fit_dewarp(sc.image, sc.grid, options);
    if (!fit.ok) {
      state.SkipWithError(("fit failed: " + fit.reason).c_str());
      return;
    }
    const DewarpMapError e = dewarp_map_error(sc, [&](const Eigen::Vector2d& d) { return fit.map->correct_point(d); });
    mean += e.between.mean_mm / 4, max = std::max(max, e.between.max_mm);
    else_mean += e.elsewhere.mean_mm / 4, else_max = std::max(else_max, e.elsewhere.max_mm);
    hidden += sc.hidden_fraction / 4;
  }
  state.counters["holes_used"] = used;
  state.counters["hidden"] = hidden;
  state.counters["between_mean_mm"] = mean;
  state.counters["between_max_mm"] = max;
  state.counters["elsewhere_mean_mm"] = else_mean;
  state.counters["elsewhere_max_mm"] = else_max;
}
BENCHMARK(BM_DewarpFit)->Args({0, 0})->Args({1, 0})->Args({0, 1})->Args({1, 1})->Unit(benchmark::kMillisecond);

// Robustness: `count` noisy scenes with 40 % of the holes hidden and 40 dust specks, orientations
// 37 deg apart, edge displacement 10, 12.5 and 15 px (at 1024^2). Args: size, count. Timed: nothing
// useful (one pass renders and fits them all). Counters: failed fits, scenes whose between-holes mean
// exceeds the 0.05 mm goal (a mis-indexed patch shows as millimetres), the worst mean and max.
void BM_DewarpRobustness(benchmark::State& state) {
  const int size = int(state.range(0)), count = int(state.range(1));
  int failed = 0, off = 0;
  double worst_mean = 0, worst_max = 0;
  for (auto _ : state) {
    failed = off = 0;
    worst_mean = worst_max = 0;
    for (int k = 0; k < count; ++k) {
      DewarpSceneOptions o;
      o.size = size;
      o.pixel_mm = 0.38 * size / 1024.0;  // the same 0.38 mm pixels at every size
      o.seed = uint64_t(100 + k);
      o.orbit_deg = 37.0 * k;
      o.noise_sigma = 0.05, o.hidden_fraction = 0.4, o.dust_count = 40;
      o.edge_displacement_px = 10 + (k % 3) * 2.5;
      const DewarpScene s = make_dewarp_scene(o);
      const DewarpFit fit = fit_dewarp(s.image, s.grid);
      if (!fit.ok) {
        ++failed;
        continue;
      }
      const DewarpMapError e = dewarp_map_error(s, [&](const Eigen::Vector2d& d) { return fit.map->correct_point(d); });
      off += e.between.mean_mm > 0.05;
      worst_mean = std::max(worst_mean, e.between.mean_mm), worst_max = std::max(worst_max, e.between.max_mm);
    }
  }
  state.counters["scenes"] = count;
  state.counters["failed"] = failed;
  state.counters["off_goal"] = off;
  state.counters["worst_mean_mm"] = worst_mean;
  state.counters["worst_max_mm"] = worst_max;
}
BENCHMARK(BM_DewarpRobustness)->Args({512, 24})->Args({1024, 8})->Iterations(1)->Unit(benchmark::kSecond);

const DewarpMap& dewarp_map() {
  static const DewarpMap map = *fit_dewarp(dewarp_scene(0, 0).image, dewarp_scene(0, 0).grid).map;
  return map;
}

// `dewarp apply` on a 16-bit 1024^2 image with the map loaded and its remap tables built. Arg:
// OpenCV threads (0: its default, every core; 1: one core, the time a busy machine still gives).
void BM_DewarpApply(benchmark::State& state) {
  const int threads_before = cv::getNumThreads();
  if (state.range(0) > 0) cv::setNumThreads(int(state.range(0)));
  const DewarpScene& s = dewarp_scene(0, 0);
  cv::Mat image(s.image.height, s.image.width, CV_16U);
  for (int v = 0; v < image.rows; ++v)
    for (int u = 0; u < image.cols; ++u) image.at<uint16_t>(v, u) = uint16_t(s.image.at(u, v));
  const DewarpMap& map = dewarp_map();
  benchmark::DoNotOptimize(map.correct_image(image));  // builds the tables
  for (auto _ : state) benchmark::DoNotOptimize(map.correct_image(image));
  cv::setNumThreads(threads_before);
}
BENCHMARK(BM_DewarpApply)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// The one-off cost after loading a map: its remap tables (a fresh map each time).
void BM_DewarpRemapTables(benchmark::State& state) {
  const nlohmann::json j = dewarp_map().to_json();
  const cv::Mat image(1024, 1024, CV_16U, cv::Scalar(1000));
  for (auto _ : state) {
    const DewarpMap map = DewarpMap::from_json(j, "bench");
    benchmark::DoNotOptimize(map.correct_image(image));
  }
}
BENCHMARK(BM_DewarpRemapTables)->Unit(benchmark::kMillisecond);

// ---- Point tools ----

// make_lumpy_surface(159): 4 * 159 * 158 = 100,488 triangles.
const TriangleMesh& big_mesh() {
  static const TriangleMesh mesh = make_lumpy_surface(159);
  return mesh;
}

void BM_ClosestPointIndexBuild(benchmark::State& state) {
  for (auto _ : state) {
    MeshClosestPoint index(big_mesh(), "bench");
    benchmark::DoNotOptimize(index.triangle_count());
  }
  state.counters["triangles"] = double(big_mesh().triangles.size());
}
BENCHMARK(BM_ClosestPointIndexBuild)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ClosestPointQueries(benchmark::State& state) {
  const MeshClosestPoint index(big_mesh(), "bench");
  std::vector<Eigen::Vector3d> queries = sample_surface(big_mesh(), size_t(state.range(0)), 3);
  std::mt19937_64 rng(4);
  std::normal_distribution<double> gauss(0, 2.0);
  for (auto& q : queries) q += draw3(gauss, rng);
  for (auto _ : state) benchmark::DoNotOptimize(index.closest(queries));
  state.SetItemsProcessed(int64_t(state.iterations()) * state.range(0));
}
BENCHMARK(BM_ClosestPointQueries)->Arg(5000)->Unit(benchmark::kMillisecond)->UseRealTime();

// The same queries searched from their closest points before a 0.5 mm move, as ICP does.
void BM_ClosestPointQueriesNear(benchmark::State& state) {
  const MeshClosestPoint index(big_mesh(), "bench");
  std::vector<Eigen::Vector3d> queries = sample_surface(big_mesh(), size_t(state.range(0)), 3);
  std::mt19937_64 rng(4);
  std::normal_distribution<double> gauss(0, 2.0);
  for (auto& q : queries) q += draw3(gauss, rng);
  const std::vector<SurfacePoint> before = index.closest(queries);
  for (auto& q : queries) q += Eigen::Vector3d(0.3, -0.2, 0.35);
  for (auto _ : state) benchmark::DoNotOptimize(index.closest(queries, before));
  state.SetItemsProcessed(int64_t(state.iterations()) * state.range(0));
}
BENCHMARK(BM_ClosestPointQueriesNear)->Arg(5000)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_IcpPointToPlane(benchmark::State& state) {
  const MeshClosestPoint index(big_mesh(), "bench");
  const size_t n = size_t(state.range(0));
  const Pose truth = pose_from_rotation_vector(Eigen::Vector3d(0.1, 0.4, -0.2), Eigen::Vector3d(12, -40, 510));
  std::vector<Eigen::Vector3d> points = sample_surface(big_mesh(), n, 21);
  std::mt19937_64 rng(22);
  std::normal_distribution<double> gauss(0, 0.15);
  std::uniform_real_distribution<double> u(-1, 1);
  for (size_t i = 0; i < n; ++i) {
    if (i < n / 10) {  // an outlier: a direction, then its distance (GCC's order of old)
      const Eigen::Vector3d direction = draw3(u, rng).normalized();
      points[i] += (12.5 + 7.5 * u(rng)) * direction;
    } else {
      points[i] += draw3(gauss, rng);
    }
    points[i] = truth * points[i];
  }
  const Pose start =
      truth * pose_from_rotation_vector(Eigen::Vector3d(-0.5, 0.2, 0.9).normalized() * 8 * std::numbers::pi / 180, {5, -4, 4.8});
  IcpResult r;
  for (auto _ : state) r = icp_point_to_plane(index, points, start);
  double tre = 0, start_error = 0;
  for (const auto& v : big_mesh().vertices) {
    tre += (r.T_world_model * v - truth * v).norm();
    start_error += (start * v - truth * v).norm();
  }
  state.counters["start_surface_error_mm"] = start_error / double(big_mesh().vertices.size());
  state.counters["ok"] = r.ok;
  state.counters["surface_tre_mm"] = tre / double(big_mesh().vertices.size());
  state.counters["rms_mm"] = r.rms_mm;
  state.counters["iterations"] = r.iterations;
  state.counters["inlier_fraction"] = r.inlier_fraction;
}
BENCHMARK(BM_IcpPointToPlane)->Arg(5000)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_PivotCalibration(benchmark::State& state) {
  const Eigen::Vector3d tip(3, -5, 152), pivot(100, 50, -1200);
  const auto poses = make_pivot_poses(tip, pivot, size_t(state.range(0)), 30, 0.2, 2);
  PivotCalibration r;
  for (auto _ : state) r = pivot_calibration(poses);
  state.counters["tip_error_mm"] = (r.tip_in_tool - tip).norm();
  state.counters["rms_mm"] = r.rms_mm;
  state.counters["rotation_spread_deg"] = r.rotation_spread_deg;
}
BENCHMARK(BM_PivotCalibration)->Arg(300)->Unit(benchmark::kMicrosecond);

// 2000 registrations of 6 fiducials with isotropic FLE (0.5 mm per axis) against the prediction
// at a target inside the fiducials and one 150 mm out.
void BM_FitzpatrickWestMonteCarlo(benchmark::State& state) {
  const std::vector<Eigen::Vector3d> moving = {{0, 0, 0},   {80, 10, 5},  {20, 90, -10},
                                               {-30, 40, 60}, {60, 70, 40}, {10, -20, 50}};
  const std::vector<Eigen::Vector3d> targets = {{25, 30, 25}, {150, 40, -30}};
  const Pose truth = pose_from_rotation_vector(Eigen::Vector3d(0.2, -1, 0.4).normalized() * 0.6, {40, -20, 300});
  std::vector<Eigen::Vector3d> fixed;
  for (const auto& m : moving) fixed.push_back(truth * m);
  const double sigma = 0.5;
  std::vector<double> ratio(targets.size());
  for (auto _ : state) {
    std::mt19937_64 rng(11);
    std::normal_distribution<double> gauss(0, sigma);
    std::vector<double> tre2(targets.size(), 0.0);
    for (int trial = 0; trial < 2000; ++trial) {
      std::vector<Eigen::Vector3d> noisy = moving;
      for (auto& p : noisy) p += draw3(gauss, rng);
      const PointRegistration r = register_points(noisy, fixed, {}, "bench");
      for (size_t k = 0; k < targets.size(); ++k) tre2[k] += (r.transform * targets[k] - truth * targets[k]).squaredNorm();
    }
    for (size_t k = 0; k < targets.size(); ++k)
      ratio[k] = std::sqrt(tre2[k] / 2000) / predicted_tre_rms(moving, targets[k], sigma * std::sqrt(3.0));
  }
  state.counters["inner_target_measured_over_predicted"] = ratio[0];
  state.counters["outer_target_measured_over_predicted"] = ratio[1];
}
BENCHMARK(BM_FitzpatrickWestMonteCarlo)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace fluoro

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
  const Image img = log_domain_xray(scene.line_integral);
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
  fiducial_bounds(phantom, &lo, &hi);
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
  const Image img = log_domain_xray(render_calibration_scene(phantom, view_1024(false), rendering(state.range(1) != 0, 1)).line_integral);
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
  fiducial_bounds(phantom, &lo, &hi);
  std::map<std::string, double> mean, worst;
  for (auto _ : state) {
    mean.clear();
    worst.clear();
    for (int seed = 1; seed <= seeds; ++seed) {
      const CalibrationScene scene =
          render_calibration_scene(phantom, view_1024(state.range(2) != 0), rendering(noisy, uint64_t(seed)));
      const Image img = log_domain_xray(scene.line_integral);
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
