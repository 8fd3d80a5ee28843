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
    r.blur_sigma_px = 0.5;
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
    return 0;
  }
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  return 0;
}
