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
#include "engine/pose.hpp"
#include <chrono>
#include <algorithm>

using namespace fluoro;

int main(int argc, char** argv) {
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
      const NailDetection nd = detect_nail(x, f * 10 / 1500, f * 10 / 300, 2);
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
      const NailPoseEstimate gen = fit_nail_pose(x, s.nail, s.camera.K, fp.T_camera_nail, nd.band.width_px, occ, gx, gz);
      report("generic", gen.T_camera_nail);
      {
        const NailPoseEstimate tt = fit_nail_pose(x, s.nail, s.camera.K, tn, nd.band.width_px, occ, gx, gz);
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
