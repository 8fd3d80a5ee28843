// Distal locking: scene writer (for looking at), and later the speed and the sweep.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "datasets/calibration_phantom.hpp"
#include "datasets/distal_locking_scene.hpp"
#include "engine/image_io.hpp"
#include "pipelines/distal_locking/guide_localisation.hpp"
#include "pipelines/distal_locking/nail_detection.hpp"
#include "pipelines/distal_locking/nail_pose.hpp"
#include "pipelines/distal_locking/distal_locking.hpp"
#include <random>
#include <vector>
#include "engine/pose.hpp"
#include <chrono>
#include <algorithm>

using namespace fluoro;

namespace {

constexpr double kPi = 3.14159265358979323846;

Eigen::Isometry3d camera_from_world(const PinholeCamera& c) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = c.R;
  T.translation() = c.t;
  return T;
}

double axis_angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::min(1.0, std::abs(a.normalized().dot(b.normalized())))) * 180.0 / kPi;
}

// One generated case's errors against the truth.
struct CaseResult {
  bool guide_ok = false, pairing_correct = false, ok = false;
  double guide_rot_deg = 0, guide_trans_mm = 0, axis_deg = 0, entry_exit_mm = 0, seconds = 0;
  std::string reason;
};

CaseResult evaluate(const DistalScene& s, const Image& x, NailMode mode) {
  CaseResult c;
  const auto t0 = std::chrono::steady_clock::now();
  const DistalLocking r = locate_for_distal_locking(x, s.camera, s.guide, s.nail, mode);
  c.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  c.guide_ok = r.guide_ok;
  c.reason = r.failure_reason;
  const Eigen::Isometry3d truth_guide = camera_from_world(s.camera) * s.T_world_guide;
  if (r.guide_ok) {
    c.guide_rot_deg = rotation_angle_deg(s.T_world_guide.inverse() * r.T_world_guide);
    c.guide_trans_mm = (s.T_world_guide.translation() - r.T_world_guide.translation()).norm();
    c.pairing_correct = true;
    const auto& loc = r.guide.localisation;
    for (int id : loc.matched_ids) {
      const Eigen::Vector2d p = project_pose(s.camera.K, truth_guide, s.guide.spheres_mm[size_t(id)]);
      if ((p - r.guide.circles[size_t(loc.detection_of[size_t(id)])].centre_px).norm() > 2.0) c.pairing_correct = false;
    }
  }
  if (!r.ok) return c;
  c.ok = true;
  c.axis_deg = axis_angle_deg(r.T_world_nail.linear().col(2), s.T_world_nail.linear().col(2));
  const Eigen::Vector3d g = s.T_world_guide * Eigen::Vector3d(0, 0, 10);
  double sum = 0;
  for (size_t k = 0; k < s.nail.holes.size(); ++k) {
    const Eigen::Vector3d a = s.T_world_nail * (s.nail.holes[k].center_mm - Eigen::Vector3d(0, 0, 5));
    const Eigen::Vector3d b = s.T_world_nail * (s.nail.holes[k].center_mm + Eigen::Vector3d(0, 0, 5));
    const bool a_entry = (a - g).norm() < (b - g).norm();
    sum += (r.holes[k].entry_mm - (a_entry ? a : b)).norm() + (r.holes[k].exit_mm - (a_entry ? b : a)).norm();
  }
  c.entry_exit_mm = sum / double(2 * s.nail.holes.size());
  return c;
}

// Random views: tilt given, its azimuth, roll, depth, offsets, gap, misalignment drawn.
DistalView random_view(std::mt19937_64& rng, double tilt, int pixels) {
  std::uniform_real_distribution<double> u(0, 1);
  DistalView v;
  v.pixels = pixels;
  v.tilt_deg = tilt;
  v.tilt_azimuth_deg = 360 * u(rng);
  v.nail_roll_deg = 180 * u(rng);
  v.nail_depth_mm = 600 + 250 * u(rng);
  v.nail_offset_mm = Eigen::Vector2d(-20 + 40 * u(rng), -20 + 40 * u(rng));
  v.guide_gap_mm = 20 + 40 * u(rng);
  v.guide_misalignment_deg = 5 * u(rng);
  v.guide_offset_mm = Eigen::Vector3d(-5 + 10 * u(rng), -5 + 10 * u(rng), 0);
  return v;
}

int sweep(int per_tilt, int pixels, double photons, int hidden, const char* mode_name) {
  const NailMode mode = std::strcmp(mode_name, "interactive") == 0 ? NailMode::interactive : NailMode::generic;
  std::mt19937_64 rng(42);
  std::printf("# sweep: %d images per tilt, %dx%d, photons %g, hidden spheres %d, mode %s\n", per_tilt, pixels, pixels, photons,
              hidden, mode_name);
  std::printf("%6s %5s %8s %8s %10s %10s %10s %10s %10s %8s\n", "tilt", "n", "success", "pairing", "guide_deg", "guide_mm",
              "axis_deg", "axis_max", "entry_mm", "time_s");
  for (double tilt : {0.0, 2.5, 5.0, 7.5, 10.0, 12.5, 15.0}) {
    int ok = 0, guide_ok = 0, pairing = 0;
    double gr = 0, gt = 0, ax = 0, axmax = 0, ee = 0;
    std::vector<double> times;
    for (int k = 0; k < per_tilt; ++k) {
      DistalRendering r;
      r.blur_sigma_px = 0.5;
      r.photons_per_pixel = photons;
      r.hidden_spheres = hidden;
      r.seed = rng();
      const DistalView v = random_view(rng, tilt, pixels);
      const DistalScene s = render_distal_scene(v, r);
      const CaseResult c = evaluate(s, log_domain_xray(s.line_integral), mode);
      times.push_back(c.seconds);
      guide_ok += c.guide_ok;
      pairing += c.guide_ok && c.pairing_correct;
      if (c.guide_ok) gr += c.guide_rot_deg, gt += c.guide_trans_mm;
      if (c.ok) ++ok, ax += c.axis_deg, axmax = std::max(axmax, c.axis_deg), ee += c.entry_exit_mm;
      if (std::getenv("FLUORO_SWEEP_DUMP") && (!c.ok || c.axis_deg > 1.0))
        write_distal_scene(s, std::string(std::getenv("FLUORO_SWEEP_DUMP")) + "_" + std::to_string(int(tilt * 10)) + "_" + std::to_string(k));
      if (std::getenv("FLUORO_SWEEP_VERBOSE"))
        std::printf("   tilt %.1f az %.0f roll %.0f depth %.0f: ok %d axis %.3f entry %.3f guide %.3f %s\n", tilt, v.tilt_azimuth_deg,
                    v.nail_roll_deg, v.nail_depth_mm, c.ok, c.axis_deg, c.entry_exit_mm, c.guide_rot_deg, c.reason.c_str());
    }
    std::sort(times.begin(), times.end());
    std::printf("%6.1f %5d %8.3f %8.3f %10.4f %10.4f %10.4f %10.4f %10.4f %8.3f\n", tilt, per_tilt, double(ok) / per_tilt,
                guide_ok ? double(pairing) / guide_ok : 0.0, guide_ok ? gr / guide_ok : 0.0, guide_ok ? gt / guide_ok : 0.0,
                ok ? ax / ok : 0.0, axmax, ok ? ee / ok : 0.0, times[times.size() / 2]);
    std::fflush(stdout);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 1 && std::strcmp(argv[1], "--sweep") == 0) {
    // --sweep [per_tilt] [pixels] [photons] [hidden] [generic|interactive]
    return sweep(argc > 2 ? std::atoi(argv[2]) : 20, argc > 3 ? std::atoi(argv[3]) : 512, argc > 4 ? std::atof(argv[4]) : 0,
                 argc > 5 ? std::atoi(argv[5]) : 0, argc > 6 ? argv[6] : "generic");
  }
  if (argc > 2 && std::strcmp(argv[1], "--scene") == 0) {
    DistalView v;
    DistalRendering r;
    if (argc > 3) v.tilt_deg = std::atof(argv[3]);
    if (argc > 4) v.pixels = std::atoi(argv[4]);
    r.photons_per_pixel = argc > 5 ? std::atof(argv[5]) : 0;
    if (argc > 6) v.tilt_azimuth_deg = std::atof(argv[6]);
    r.blur_sigma_px = 0.5;
    const DistalScene s = render_distal_scene(v, r);
    write_distal_scene(s, argv[2]);
    const Image x = log_domain_xray(s.line_integral);
    float lo = 1e30f, hi = -1e30f;
    for (float p : x.pixels) lo = std::min(lo, p), hi = std::max(hi, p);
    write_png(x, std::string(argv[2]) + "_view.png", lo, hi);
    return 0;
  }
  if (argc > 1 && std::strcmp(argv[1], "--try") == 0) {
    DistalView v;
    DistalRendering r;
    if (argc > 2) v.tilt_deg = std::atof(argv[2]);
    if (argc > 3) v.pixels = std::atoi(argv[3]);
    r.photons_per_pixel = argc > 4 ? std::atof(argv[4]) : 0;
    r.hidden_spheres = argc > 5 ? std::atoi(argv[5]) : 0;
    r.blur_sigma_px = argc > 6 ? std::atof(argv[6]) : 0.5;
    if (argc > 7) v.tilt_azimuth_deg = std::atof(argv[7]);
    const DistalScene s = render_distal_scene(v, r);
    const Image x = log_domain_xray(s.line_integral);
    const auto t0 = std::chrono::steady_clock::now();
    const GuideDetection g = localise_guide(x, s.guide, s.camera.K);
    const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const Eigen::Isometry3d T_cw = [&] { Eigen::Isometry3d T = Eigen::Isometry3d::Identity(); T.linear() = s.camera.R; T.translation() = s.camera.t; return T; }();
    const Eigen::Isometry3d truth = T_cw * s.T_world_guide;
    std::printf("circles %zu ok %d reason '%s' matched %zu rms %.3f max %.3f second %d time %.3f\n", g.circles.size(), g.localisation.ok,
                g.localisation.failure_reason.c_str(), g.localisation.matched_ids.size(), g.localisation.rms_px, g.localisation.max_px,
                g.localisation.second_best_pairs, dt);
    if (g.localisation.ok) {
      const Eigen::Isometry3d e = truth.inverse() * g.localisation.T_camera_guide;
      std::printf("guide error: rot %.4f deg, trans %.4f mm (z %.4f)\n", rotation_angle_deg(e), e.translation().norm(),
                  (g.localisation.T_camera_guide.translation() - truth.translation()).z());
      int wrong = 0;
      for (int i = 0; i < int(s.guide.spheres_mm.size()); ++i) {
        const int d = g.localisation.detection_of[size_t(i)];
        if (d < 0) continue;
        const Eigen::Vector2d p = project_pose(s.camera.K, truth, s.guide.spheres_mm[size_t(i)]);
        if ((p - g.circles[size_t(d)].centre_px).norm() > 1.0) ++wrong;
        std::printf("  %d: %.3f px r %.2f cov %.2f crowded %d\n", i, (p - g.circles[size_t(d)].centre_px).norm(), g.circles[size_t(d)].radius_px, g.circles[size_t(d)].edge_coverage, int(g.circles[size_t(d)].crowded));
      }
      std::printf("pairs farther than 1 px from truth: %d\n", wrong);
    }
    {
      const auto t1 = std::chrono::steady_clock::now();
      const double f = s.camera.K(0, 0);
      const NailDetection nd = detect_nail(x, s.nail, f * 10 / 1500, f * 10 / 300);
      std::printf("nail ok %d '%s' width %.2f contrast %.1f time %.3f\n", nd.ok, nd.failure_reason.c_str(), nd.band.width_px, nd.band.contrast,
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count());
      const Eigen::Isometry3d tn = T_cw * s.T_world_nail;
      std::printf("true width ~ %.2f\n", f * 10 / tn.translation().z());
      for (const auto& hh : s.nail.holes) { auto p = project_pose(s.camera.K, tn, hh.center_mm); std::printf("true hole %.2f %.2f\n", p.x(), p.y()); }
      for (const auto& e : nd.holes) std::printf("hole %.2f %.2f major %.2f minor %.2f angle %.1f\n", e.centre_px.x(), e.centre_px.y(), e.major_px, e.minor_px, e.angle_deg);
      const Eigen::Vector3d gx = g.localisation.T_camera_guide.linear().col(0), gz = g.localisation.T_camera_guide.linear().col(2);
      const auto report = [&](const char* name, const CameraPose& T) {
        const Eigen::Isometry3d e = tn.inverse() * T;
        std::printf("%s: rot %.3f deg, z-axis %.3f deg, trans %.3f mm, depth %.3f mm\n", name, rotation_angle_deg(e),
                    std::acos(std::min(1.0, T.linear().col(2).dot(tn.linear().col(2)))) * 180 / 3.14159265, e.translation().norm(),
                    (T.translation() - tn.translation()).z());
      };
      std::vector<DarkCircle> occ = g.circles;
      for (const auto& X : s.guide.spheres_mm) {
        DarkCircle c;
        c.centre_px = project_pose(s.camera.K, g.localisation.T_camera_guide, X);
        c.radius_px = s.camera.K(0, 0) * 1.5 / (g.localisation.T_camera_guide * X).z();
        occ.push_back(c);
      }
      const NailPoseEstimate fp = fronto_parallel_nail_pose(nd, s.nail, s.camera.K, gx, gz);
      report("fronto-parallel", fp.T_camera_nail);
      const auto t2 = std::chrono::steady_clock::now();
      const NailPoseEstimate gen = fit_nail_pose(x, s.nail, s.camera.K, {fp.T_camera_nail}, nd.band.width_px, occ, gx, gz);
      report("generic", gen.T_camera_nail);
      {
        const NailPoseEstimate tt = fit_nail_pose(x, s.nail, s.camera.K, {tn}, nd.band.width_px, occ, gx, gz);
        report("generic-from-truth", tt.T_camera_nail);
        std::printf("from truth rms %.2f mirror %.2f\n", tt.rms, tt.mirror_rms);
      }
      std::printf("generic rms %.2f mirror %.2f evals %d time %.3f\n", gen.rms, gen.mirror_rms, gen.evaluations,
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - t2).count());
    }
    return 0;
  }
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  return 0;
}
