// fluoro demo --calibration: the calibration chain on generated images with known truth. A dewarp
// grid X-ray and a calibration-phantom X-ray are made at one C-arm orientation, both bent by the
// same image-intensifier distortion; the grid's map is fitted, the phantom's balls are detected,
// corrected through the map and calibrated; the errors against the truth are printed.
#include <Eigen/Geometry>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <random>

#include "apps/fluoro/demo_calibration.hpp"
#include "apps/fluoro/provenance.hpp"
#include "apps/fluoro/result_files.hpp"
#include "datasets/calibration_phantom.hpp"
#include "datasets/dewarp_grid.hpp"
#include "engine/error.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "pipelines/calibration/dewarp_fit.hpp"
#include "pipelines/calibration/image_calibration.hpp"
#include "pipelines/calibration/volume_reprojection.hpp"

namespace fluoro::cli {
namespace {

// The true camera of the corrected image. The map's corrected frame is its own choice (a
// similarity of the ideal detector frame: scale, turn, offset); it is measured on the grid's
// holes, whose ideal and distorted positions the truth knows, and applied to the true P.
PinholeCamera truth_in_corrected_frame(const DewarpScene& grid, const DewarpMap& map, const PinholeCamera& ideal) {
  std::vector<Eigen::Vector2d> from, to;
  for (const auto& h : grid.holes)
    if (const auto c = map.correct_point(h.distorted_px)) from.push_back(h.ideal_px), to.push_back(*c);
  Eigen::MatrixXd a(2, from.size()), b(2, to.size());
  for (size_t i = 0; i < from.size(); ++i) a.col(long(i)) = from[i], b.col(long(i)) = to[i];
  const Eigen::Matrix3d similarity = Eigen::umeyama(a, b, true);
  return camera_from_projection(similarity * ideal.projection_matrix(), map.width(), map.height(), "demo truth");
}

std::vector<uint16_t> to_u16(const Image& image) {
  std::vector<uint16_t> out(image.pixels.size());
  for (size_t i = 0; i < out.size(); ++i) out[i] = uint16_t(std::clamp(std::lround(image.pixels[i]), 0L, 65535L));
  return out;
}

}  // namespace

void run_calibration_demo(const CalibrationDemoOptions& o) {
  namespace fs = std::filesystem;
  make_output_directory(o.out_dir);
  const fs::path dir(o.out_dir);
  nlohmann::json summary;
  auto t = std::chrono::steady_clock::now();

  // 1. The dewarp grid at this C-arm orientation: noise, dust and a clamp hiding a fifth of the holes.
  DewarpSceneOptions go;
  go.size = o.pixels;
  go.orbit_deg = o.orbit_deg;
  go.noise_sigma = 0.03;
  go.hidden_fraction = 0.2;
  go.dust_count = 12;
  go.seed = 7;
  const DewarpScene grid = make_dewarp_scene(go);
  save_dewarp_scene(grid, (dir / "grid_xray.png").string(), (dir / "GRID.json").string());
  summary["timings_s"]["make_grid_xray"] = seconds_since(t);

  t = std::chrono::steady_clock::now();
  const DewarpFit fit = fit_dewarp(grid.image, grid.grid);
  // No input files: the demo makes its images in memory (and writes them for a rerun).
  const nlohmann::json origin = provenance("demo --calibration",
                                           {{"pixels", o.pixels}, {"orbit_deg", o.orbit_deg}, {"ring", o.ring}},
                                           nlohmann::json::array());
  summary["timings_s"]["dewarp_fit"] = seconds_since(t);
  if (!fit.ok) throw std::runtime_error("the demo's grid could not be fitted: " + fit.reason);
  const DewarpMap& map = *fit.map;
  // The same documents the commands write (without inputs: the demo made them).
  nlohmann::json map_doc = dewarp_fit_document(fit, grid.grid, grid.image.width, grid.image.height);
  map_doc["provenance"] = origin;
  write_json(map_doc, (dir / "MAP.json").string());
  const DewarpMapError dewarp_error =
      dewarp_map_error(grid, [&](const Eigen::Vector2d& p) { return map.correct_point(p); });

  // 2. The phantom on the image intensifier, seen through the same distortion.
  t = std::chrono::steady_clock::now();
  const PhantomModel phantom = o.ring ? ring_phantom() : tower_phantom();
  PhantomView view;
  view.pixels = o.pixels;
  view.pixel_mm = go.pixel_mm * 1024.0 / o.pixels;
  view.axis_turn_deg = 20;
  view.tilt_deg = 4;
  view.tilt_azimuth_deg = 30;
  XrayRendering rendering;
  rendering.blur_sigma_px = 0.7;
  rendering.photons_per_pixel = 150;
  rendering.clutter_balls = 3;
  const CalibrationScene scene = render_calibration_scene(phantom, view, rendering);
  Image xray = distort_image(log_domain_xray(scene.line_integral), grid.distortion);
  for (int v = 0; v < xray.height; ++v)  // the image intensifier's round field of view, black outside
    for (int u = 0; u < xray.width; ++u)
      if ((Eigen::Vector2d(u, v) - grid.fov_centre_px).norm() > grid.fov_radius_px) xray.at(u, v) = 0;
  write_png_u16(to_u16(xray), xray.width, xray.height, (dir / "phantom_xray.png").string());
  write_json(phantom_model_to_json(phantom), (dir / "PHANTOM.json").string());
  summary["timings_s"]["make_phantom_xray"] = seconds_since(t);

  // 3. Detect on the distorted image, correct the centres through the map, calibrate.
  t = std::chrono::steady_clock::now();
  const ImageCalibration result = calibrate_image(xray, phantom, &map);
  const CameraCalibration& cal = result.calibration;
  summary["timings_s"]["calibrate"] = seconds_since(t);
  if (!cal.ok) throw std::runtime_error("the demo's phantom could not be calibrated: " + cal.failure_reason);
  nlohmann::json camera_doc = calibration_document(result, phantom);
  camera_doc["provenance"] = origin;
  write_json(camera_doc, (dir / "CAMERA.json").string());
  const PinholeCamera truth = truth_in_corrected_frame(grid, map, scene.camera);
  write_camera(truth, (dir / "truth_camera.json").string());

  Eigen::Vector3d lo, hi;
  fiducial_bounds(phantom, &lo, &hi);
  const ReprojectionGap gap = volume_reprojection_gap(cal.camera, truth, lo, hi);
  const double source_error = (cal.camera.source() - truth.source()).norm();
  // The same image without the dewarp: what calibrating a distorted image costs.
  const CameraCalibration uncorrected = calibrate_image(xray, phantom).calibration;
  ReprojectionGap gap_raw;
  double source_error_raw = 0;
  if (uncorrected.ok) {
    // Compared in the distorted image, where its pixels live: the true pixel is the distorted truth.
    gap_raw = volume_reprojection_gap(
        uncorrected.camera, [&](const Eigen::Vector3d& x) { return grid.distortion.distort(scene.camera.project(x)); },
        lo, hi);
    source_error_raw = (uncorrected.camera.source() - scene.camera.source()).norm();
  }

  summary["status"] = "ok";
  summary["provenance"] = origin;
  summary["c_arm_orbit_deg"] = o.orbit_deg;
  summary["dewarp"] = {{"holes_found", fit.holes_found},
                       {"holes_used", fit.holes_used},
                       {"residual_px", {{"mean", fit.residual_mean_px}, {"max", fit.residual_max_px}}},
                       {"error_between_holes_mm", {{"mean", dewarp_error.between.mean_mm}, {"max", dewarp_error.between.max_mm}}}};
  summary["calibration"] = {{"phantom", o.ring ? "ring" : "tower"},
                            {"fiducials_found", result.balls_found},
                            {"fiducials_matched", cal.fiducials.size()},
                            {"reprojection_px", {{"rms", cal.rms_px}, {"max", cal.max_px}}},
                            {"volume_reprojection_error_px", {{"mean", gap.mean_px}, {"max", gap.max_px}}},
                            {"source_error_mm", source_error}};
  if (uncorrected.ok)
    summary["calibration_without_dewarp"] = {{"volume_reprojection_error_px", {{"mean", gap_raw.mean_px}, {"max", gap_raw.max_px}}},
                                             {"source_error_mm", source_error_raw}};
  write_json(summary, (dir / "summary.json").string());

  std::printf("fluoro demo --calibration: %dx%d C-arm images at orbit %.0f deg, image-intensifier distortion of %.1f px at the edge\n",
              o.pixels, o.pixels, o.orbit_deg, go.edge_displacement_px * o.pixels / 1024.0);
  std::printf("  dewarp:    %d holes found, %d used (a clamp hides %.0f %%), fit residual %.3f px mean; "
              "error between the holes %.4f mm mean, %.4f mm max (plate mm)\n",
              fit.holes_found, fit.holes_used, 100 * grid.hidden_fraction, fit.residual_mean_px, dewarp_error.between.mean_mm,
              dewarp_error.between.max_mm);
  std::printf("  calibrate: %s phantom, %zu dark blobs, %zu balls matched, reprojection rms %.3f px\n",
              o.ring ? "ring" : "tower", result.balls_found, cal.fiducials.size(), cal.rms_px);
  std::printf("             through the phantom's volume: %.3f px mean, %.3f px max from the true camera; source %.2f mm off\n",
              gap.mean_px, gap.max_px, source_error);
  if (uncorrected.ok)
    std::printf("             without the dewarp:             %.3f px mean, %.3f px max; source %.2f mm off\n",
                gap_raw.mean_px, gap_raw.max_px, source_error_raw);
  std::printf("  files:     %s/{grid_xray.png, GRID.json, MAP.json, phantom_xray.png, PHANTOM.json, CAMERA.json, truth_camera.json, summary.json}\n",
              o.out_dir.c_str());
  std::printf("  again:     fluoro dewarp fit --image %s/grid_xray.png --grid %s/GRID.json --out MAP.json\n",
              o.out_dir.c_str(), o.out_dir.c_str());
  std::printf("             fluoro calibrate --image %s/phantom_xray.png --phantom %s/PHANTOM.json --dewarp MAP.json --out CAMERA.json\n",
              o.out_dir.c_str(), o.out_dir.c_str());
}

}  // namespace fluoro::cli
