// Distal locking (docs/distal_locking.md): the speed of the whole method on a 1024^2 image (Google
// Benchmark), and three reports on generated images with known truth:
//   fluoro_distal_locking_bench --sweep [per_tilt] [pixels] [photons] [hidden] [generic|interactive]
//     success rate and errors against the tilt (views drawn at random otherwise);
//   fluoro_distal_locking_bench --pnp [images] [pixels]
//     the guide's pose from the same pairs: ours (P3P hypotheses + LM) and DLT + LM against
//     OpenCV's solvePnP ITERATIVE, EPNP and SQPNP (rotation and translation error, time);
//   fluoro_distal_locking_bench --scene PREFIX [tilt] [pixels] [photons] [azimuth]
//     writes one scene as fluoro distal-lock reads it.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "datasets/calibration_phantom.hpp"
#include "datasets/distal_locking_scene.hpp"
#include "engine/image_io.hpp"
#include "pipelines/distal_locking/guide_localisation.hpp"
#include "pipelines/distal_locking/distal_locking.hpp"
#include "pipelines/calibration/projection_dlt.hpp"
#include <Eigen/SVD>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <random>
#include <vector>
#include "engine/pose.hpp"
#include <chrono>
#include <algorithm>

using namespace fluoro;

namespace {



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
  const Eigen::Isometry3d truth_guide = s.camera.camera_from_world() * s.T_world_guide;
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

// The guide's pose from the pairs our matching found, by each solver, against the truth.
int pnp_table(int images, int pixels) {
  std::mt19937_64 rng(7);
  struct Row {
    const char* name;
    double rot = 0, trans = 0, seconds = 0;
    int n = 0, failed = 0;
  };
  Row rows[] = {{"ours: P3P hypotheses + LM"}, {"DLT + LM"}, {"solvePnP ITERATIVE"}, {"solvePnP EPNP"}, {"solvePnP SQPNP"}};
  for (int k = 0; k < images; ++k) {
    DistalRendering r;
    r.blur_sigma_px = 0.5;
    r.photons_per_pixel = 20000;
    r.seed = rng();
    const DistalView v = random_view(rng, 15.0 * double(k % 7) / 6.0, pixels);
    const DistalScene s = render_distal_scene(v, r);
    const Image x = log_domain_xray(s.line_integral);
    const GuideDetection g = localise_guide(x, s.guide, s.camera.K);
    if (!g.localisation.ok) continue;
    const Eigen::Isometry3d truth = s.camera.camera_from_world() * s.T_world_guide;
    std::vector<Eigen::Vector3d> X;
    std::vector<Eigen::Vector2d> u;
    std::vector<cv::Point3d> Xcv;
    std::vector<cv::Point2d> ucv;
    for (int id : g.localisation.matched_ids) {
      X.push_back(s.guide.spheres_mm[size_t(id)]);
      u.push_back(g.circles[size_t(g.localisation.detection_of[size_t(id)])].centre_px);
      Xcv.emplace_back(X.back().x(), X.back().y(), X.back().z());
      ucv.emplace_back(u.back().x(), u.back().y());
    }
    const auto record = [&](Row& row, const Eigen::Isometry3d& T, double sec) {
      const Eigen::Isometry3d e = truth.inverse() * T;
      row.rot += rotation_angle_deg(e);
      row.trans += (T.translation() - truth.translation()).norm();
      row.seconds += sec;
      ++row.n;
    };
    const auto timed = [](auto&& f) {
      const auto t0 = std::chrono::steady_clock::now();
      f();
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    };
    {
      // Ours as the command runs it: the pairing's pose (P3P hypotheses, then LM on the pairs);
      // its time is the matching's, which includes the search.
      CameraPose T;
      const double sec = timed([&] {
        std::vector<Eigen::Vector2d> centres;
        for (const auto& c : g.circles) centres.push_back(c.centre_px);
        T = match_guide(s.guide, centres, s.camera.K).T_camera_guide;
      });
      record(rows[0], T, sec);
    }
    {
      CameraPose T = CameraPose::Identity();
      bool ok = false;
      const double sec = timed([&] {
        const auto P = projection_dlt(X, u);
        if (!P) return;
        // Known K: K^-1 P is s [R | t]; R is the nearest rotation (SVD).
        const Eigen::Matrix<double, 3, 4> M = s.camera.K.inverse() * *P;
        Eigen::JacobiSVD<Eigen::Matrix3d> svd(M.leftCols<3>(), Eigen::ComputeFullU | Eigen::ComputeFullV);
        double scale = svd.singularValues().mean();
        Eigen::Matrix3d R = svd.matrixU() * svd.matrixV().transpose();
        if (R.determinant() < 0) R = -R, scale = -scale;
        T.linear() = R;
        T.translation() = M.col(3) / scale;
        if (T.translation().z() < 0) return;
        T = refine_pose(s.camera.K, T, X, u);
        ok = true;
      });
      if (ok) record(rows[1], T, sec); else ++rows[1].failed;
    }
    cv::Mat Kcv;
    cv::eigen2cv(s.camera.K, Kcv);
    const std::pair<int, int> methods[] = {{2, cv::SOLVEPNP_ITERATIVE}, {3, cv::SOLVEPNP_EPNP}, {4, cv::SOLVEPNP_SQPNP}};
    for (const auto& [row, flag] : methods) {
      cv::Mat rvec, tvec;
      bool ok = false;
      const double sec = timed([&] { ok = cv::solvePnP(Xcv, ucv, Kcv, cv::noArray(), rvec, tvec, false, flag); });
      if (!ok) {
        ++rows[row].failed;
        continue;
      }
      cv::Matx33d Rcv;
      cv::Rodrigues(rvec, Rcv);
      CameraPose T = CameraPose::Identity();
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) T.linear()(i, j) = Rcv(i, j);
        T.translation()(i) = tvec.at<double>(i);
      }
      record(rows[size_t(row)], T, sec);
    }
  }
  std::printf("# the guide's pose from the same pairs, %d images %dx%d (tilt 0-15 deg, 20000 photons/pixel)\n", images, pixels, pixels);
  std::printf("| solver | images | rotation error (deg, mean) | translation error (mm, mean) | time (ms, mean) |\n|---|---|---|---|---|\n");
  for (const auto& r : rows)
    std::printf("| %s | %d%s | %.4f | %.4f | %.3f |\n", r.name, r.n, r.failed ? " (some failed)" : "", r.n ? r.rot / r.n : 0.0,
                r.n ? r.trans / r.n : 0.0, r.n ? 1000 * r.seconds / r.n : 0.0);
  return 0;
}

// The whole method (guide, nail, entry and exit points) on one 1024^2 image, generic mode.
void BM_DistalLock1024(benchmark::State& state) {
  DistalView v;
  v.pixels = 1024;
  v.tilt_deg = 8;
  DistalRendering r;
  r.blur_sigma_px = 0.7;
  r.photons_per_pixel = 20000;
  static const DistalScene s = render_distal_scene(v, r);
  static const Image x = log_domain_xray(s.line_integral);
  for (auto _ : state) {
    const DistalLocking out = locate_for_distal_locking(x, s.camera, s.guide, s.nail, NailMode::generic);
    benchmark::DoNotOptimize(out.ok);
  }
}
BENCHMARK(BM_DistalLock1024)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime()->Iterations(5);

}  // namespace

int main(int argc, char** argv) {
  if (argc > 1 && std::strcmp(argv[1], "--pnp") == 0)
    return pnp_table(argc > 2 ? std::atoi(argv[2]) : 40, argc > 3 ? std::atoi(argv[3]) : 512);
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
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  return 0;
}
