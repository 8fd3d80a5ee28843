// Distal locking (docs/distal_locking.md): the speed of the whole method on a 1024^2 image (Google
// Benchmark), and three reports on generated images with known truth:
//   fluoro_distal_locking_bench --sweep [per_tilt] [pixels] [photons] [hidden] [generic|interactive]
//     success rate and errors against the tilt (views drawn at random otherwise);
//   fluoro_distal_locking_bench --pnp [images] [pixels]
//     the guide's pose from the same pairs: ours (P3P hypotheses + LM) and DLT + LM against
//     OpenCV's solvePnP ITERATIVE, EPNP and SQPNP (rotation and translation error, time);
//   fluoro_distal_locking_bench --scene PREFIX [tilt] [pixels] [photons] [azimuth]
//     writes one scene as fluoro distal-lock reads it;
//   fluoro_distal_locking_bench --bitangent [per_tilt] [pixels] [photons]
//     the seed's planar pose from the holes' four outer bitangent points (IPPE) against the
//     cylinder fit, on the --sweep's views (same seed);
//   fluoro_distal_locking_bench --big-sweep PER_TILT PIXELS OUT_PREFIX
//     views, noise and occlusion all drawn (tilt 0-15 deg in steps of 1.5), both modes on every
//     image: OUT_PREFIX.csv (one row per image and mode) and OUT_PREFIX.svg (success rate and errors
//     against the tilt), the table on stdout.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "datasets/calibration_phantom.hpp"
#include "datasets/distal_locking_scene.hpp"
#include "engine/random_draws.hpp"
#include "engine/image_io.hpp"
#include "pipelines/distal_locking/guide_localisation.hpp"
#include "pipelines/distal_locking/distal_locking.hpp"
#include "pipelines/distal_locking/nail_bitangent_pose.hpp"
#include "pipelines/calibration/projection_dlt.hpp"
#include <Eigen/SVD>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <random>
#include <vector>
#include "engine/pose.hpp"
#include <chrono>
#include <algorithm>
#include <fstream>
#include <functional>
#include <map>
#include <numeric>
#include <sstream>

using namespace fluoro;

namespace {



// One generated case's errors against the truth.
struct CaseResult {
  // pairing_correct: every matched detection within 2 px of its sphere's true projection (mixes
  // the centroid's accuracy with the pairing); identity_correct: every matched detection belongs
  // to the sphere it was paired with (the visible sphere whose true projection is nearest to it,
  // within that sphere's projected radius): the correspondence alone.
  bool guide_ok = false, pairing_correct = false, identity_correct = false, ok = false;
  int wrong_ids = 0;  // matched detections that belong to another sphere or to none
  int superimposed_ids = 0;  // of those, a blob of two superimposed spheres paired with the farther
  // The view: the true and estimated angle between the hole axes and the ray through the nail's
  // centre, whether the method accepts it as fronto-parallel, the holes' smaller circularity.
  double view_dev_true = 0, view_dev_est = 0, min_circularity = 0, tie_spread_deg = 0;
  bool fronto_parallel = false;
  double guide_rot_deg = 0, guide_trans_mm = 0, axis_deg = 0, entry_exit_mm = 0, seconds = 0;
  std::string reason;
};

// How many matched detections do not belong to the sphere they were paired with: each belongs to
// the visible sphere whose true projection is nearest, if within its projected radius. Of those,
// `superimposed` counts the ones whose paired sphere's projection is within a projected radius of
// both the detection and the nearest sphere's: two spheres, one on each plane, nearly on one ray,
// which the image shows as one dark blob (either identity is the blob's).
int wrong_identities(const DistalScene& s, const DistalLocking& r, int* superimposed) {
  *superimposed = 0;
  const Eigen::Isometry3d truth_guide = s.camera.camera_from_world() * s.T_world_guide;
  const double f = 0.5 * (s.camera.K(0, 0) + s.camera.K(1, 1));
  const auto& loc = r.guide.localisation;
  int wrong = 0;
  for (int id : loc.matched_ids) {
    const Eigen::Vector2d d = r.guide.circles[size_t(loc.detection_of[size_t(id)])].centre_px;
    int owner = -1;
    double nearest = HUGE_VAL, radius = 0;
    for (int j = 0; j < int(s.guide.spheres_mm.size()); ++j) {
      if (std::find(s.hidden_ids.begin(), s.hidden_ids.end(), j) != s.hidden_ids.end()) continue;
      const Eigen::Vector3d X = truth_guide * s.guide.spheres_mm[size_t(j)];
      const double dist = (project_pose(s.camera.K, truth_guide, s.guide.spheres_mm[size_t(j)]) - d).norm();
      if (dist < nearest) nearest = dist, owner = j, radius = f * 0.5 * s.guide.sphere_diameter_mm / X.z();
    }
    if (owner != id || nearest > radius) {
      ++wrong;
      const Eigen::Vector2d own = project_pose(s.camera.K, truth_guide, s.guide.spheres_mm[size_t(id)]);
      const Eigen::Vector2d other = project_pose(s.camera.K, truth_guide, s.guide.spheres_mm[size_t(owner)]);
      *superimposed += owner >= 0 && (own - d).norm() < radius && (own - other).norm() < radius;
    }
  }
  return wrong;
}

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
    c.wrong_ids = wrong_identities(s, r, &c.superimposed_ids);
    c.identity_correct = c.wrong_ids == 0;
  }
  {
    const Eigen::Isometry3d T = s.camera.camera_from_world() * s.T_world_nail;
    c.view_dev_true = axis_angle_deg(T.translation(), T.linear().col(2));
  }
  if (!r.ok) return c;
  c.ok = true;
  c.view_dev_est = r.view_deviation_deg;
  c.tie_spread_deg = r.nail_pose.tie_spread_deg;
  c.fronto_parallel = r.fronto_parallel;
  c.min_circularity = 1;
  for (const auto& h : r.holes) c.min_circularity = std::min(c.min_circularity, h.circularity);
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
  v.nail_offset_mm = Eigen::Vector2d::Constant(-20) + 40 * draw2(u, rng);
  v.guide_gap_mm = 20 + 40 * u(rng);
  v.guide_misalignment_deg = 5 * u(rng);
  const Eigen::Vector2d guide_offset = Eigen::Vector2d::Constant(-5) + 10 * draw2(u, rng);
  v.guide_offset_mm = Eigen::Vector3d(guide_offset.x(), guide_offset.y(), 0);
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


// Hole axes and entry/exit points of an estimated nail pose against the truth, whichever end is
// the entry: per true hole, the estimated hole nearest it, its axis' two surface points paired
// with the truth's the nearer way round.
std::pair<double, double> nail_errors(const Eigen::Isometry3d& T_world_nail, const DistalScene& s) {
  const double axis = axis_angle_deg(T_world_nail.linear().col(2), s.T_world_nail.linear().col(2));
  const double R = 0.5 * s.nail.diameter_mm;
  double sum = 0;
  for (const auto& h : s.nail.holes) {
    const Eigen::Vector3d c = s.T_world_nail * h.center_mm;
    const NailHole* e = nullptr;
    for (const auto& g : s.nail.holes)
      if (!e || (T_world_nail * g.center_mm - c).norm() < (T_world_nail * e->center_mm - c).norm()) e = &g;
    const Eigen::Vector3d a = s.T_world_nail * (h.center_mm - Eigen::Vector3d(0, 0, R)), b = s.T_world_nail * (h.center_mm + Eigen::Vector3d(0, 0, R));
    const Eigen::Vector3d ea = T_world_nail * (e->center_mm - Eigen::Vector3d(0, 0, R)), eb = T_world_nail * (e->center_mm + Eigen::Vector3d(0, 0, R));
    sum += 0.5 * std::min((ea - a).norm() + (eb - b).norm(), (ea - b).norm() + (eb - a).norm());
  }
  return {axis, sum / double(s.nail.holes.size())};
}

int bitangent_table(int per_tilt, int pixels, double photons) {
  std::mt19937_64 rng(42);
  std::printf("# the seed's planar pose (outer bitangents of the hole ellipses, IPPE) and the cylinder fit, same images: %d per tilt, "
              "%dx%d, photons %g\n", per_tilt, pixels, pixels, photons);
  std::printf("| tilt (deg) | images | cylinder fit: axis (deg, mean) | entry/exit (mm, mean) | bitangents + IPPE: found | axis (deg, mean) | "
              "entry/exit (mm, mean) |\n|---|---|---|---|---|---|---|\n");
  double all[4] = {0, 0, 0, 0};
  int n_fit = 0, n_bit = 0, n_all = 0;
  for (double tilt : {0.0, 2.5, 5.0, 7.5, 10.0, 12.5, 15.0}) {
    double fa = 0, fe = 0, ba = 0, be = 0;
    int nf = 0, nb = 0;
    for (int k = 0; k < per_tilt; ++k) {
      DistalRendering r;
      r.blur_sigma_px = 0.5;
      r.photons_per_pixel = photons;
      r.seed = rng();
      const DistalView v = random_view(rng, tilt, pixels);
      const DistalScene s = render_distal_scene(v, r);
      const DistalLocking out = locate_for_distal_locking(log_domain_xray(s.line_integral), s.camera, s.guide, s.nail, NailMode::generic);
      ++n_all;
      if (!out.ok) continue;
      const auto [a, e] = nail_errors(out.T_world_nail, s);
      fa += a, fe += e, ++nf;
      const NailPoseEstimate b = bitangent_nail_pose(out.nail_detection, s.nail, s.camera.K, out.T_camera_guide.linear().col(0),
                                                     out.T_camera_guide.linear().col(2));
      if (!b.ok) continue;
      const auto [a2, e2] = nail_errors(s.camera.camera_from_world().inverse() * b.T_camera_nail, s);
      ba += a2, be += e2, ++nb;
    }
    std::printf("| %.1f | %d | %.3f | %.3f | %d | %.3f | %.3f |\n", tilt, per_tilt, nf ? fa / nf : 0.0, nf ? fe / nf : 0.0, nb,
                nb ? ba / nb : 0.0, nb ? be / nb : 0.0);
    std::fflush(stdout);
    all[0] += fa, all[1] += fe, all[2] += ba, all[3] += be, n_fit += nf, n_bit += nb;
  }
  std::printf("| all | %d | %.3f | %.3f | %d | %.3f | %.3f |\n", n_all, n_fit ? all[0] / n_fit : 0.0, n_fit ? all[1] / n_fit : 0.0, n_bit,
              n_bit ? all[2] / n_bit : 0.0, n_bit ? all[3] / n_bit : 0.0);
  return 0;
}

// --- the big sweep: every view, noise level and occlusion drawn; both modes on each image ---

std::string fmt(double v, int decimals) {
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  return b;
}

// One SVG panel: several polylines (x, y) on shared axes, with ticks, a title and a legend.
struct Series {
  std::string name, colour;
  std::vector<std::pair<double, double>> points;
  bool dashed = false;
};
void svg_panel(std::ostringstream& svg, double top, const std::string& title, const std::vector<Series>& series, double x_max,
               double y_max, const std::string& x_label) {
  const double left = 70, width = 620, height = 160;
  svg << "<g font-family='sans-serif' font-size='11'>\n";
  svg << "<text x='" << left << "' y='" << top - 8 << "' font-size='13'>" << title << "</text>\n";
  svg << "<rect x='" << left << "' y='" << top << "' width='" << width << "' height='" << height << "' fill='none' stroke='#444'/>\n";
  for (int i = 0; i <= 4; ++i) {
    const double y = top + height - height * i / 4.0;
    svg << "<line x1='" << left - 4 << "' y1='" << y << "' x2='" << left + width << "' y2='" << y << "' stroke='#ddd'/>\n";
    svg << "<text x='" << left - 8 << "' y='" << y + 4 << "' text-anchor='end'>" << fmt(y_max * i / 4.0, y_max < 5 ? 2 : 0) << "</text>\n";
  }
  for (int i = 0; i <= 5; ++i) {
    const double x = left + width * i / 5.0;
    svg << "<text x='" << x << "' y='" << top + height + 14 << "' text-anchor='middle'>" << fmt(x_max * i / 5.0, 0) << "</text>\n";
  }
  svg << "<text x='" << left + width << "' y='" << top + height + 28 << "' text-anchor='end'>" << x_label << "</text>\n";
  double legend_x = left + 200;
  for (const Series& s : series) {
    svg << "<polyline fill='none' stroke='" << s.colour << "' stroke-width='1.5'" << (s.dashed ? " stroke-dasharray='5,3'" : "")
        << " points='";
    for (const auto& [x, y] : s.points)
      svg << fmt(left + width * x / x_max, 2) << ',' << fmt(top + height - height * std::min(y, y_max) / y_max, 2) << ' ';
    svg << "'/>\n";
    svg << "<line x1='" << legend_x << "' y1='" << top - 12 << "' x2='" << legend_x + 20 << "' y2='" << top - 12 << "' stroke='" << s.colour
        << "' stroke-width='1.5'" << (s.dashed ? " stroke-dasharray='5,3'" : "") << "/>\n";
    svg << "<text x='" << legend_x + 24 << "' y='" << top - 8 << "'>" << s.name << "</text>\n";
    legend_x += 36 + 6.5 * double(s.name.size());
  }
  svg << "</g>\n";
}

struct BigRow {
  int image = 0;
  double tilt = 0, photons = 0;
  int hidden = 0;
  const char* mode = "";
  CaseResult c;
  bool success = false, flagged = false, wrong = false;
};

int big_sweep(int per_tilt, int pixels, const std::string& prefix) {
  std::mt19937_64 rng(2026);
  std::uniform_real_distribution<double> u(0, 1);
  const double photon_levels[] = {5000, 20000, 80000};
  std::vector<double> tilts;
  for (int i = 0; i <= 10; ++i) tilts.push_back(1.5 * i);
  std::vector<BigRow> rows;
  std::ofstream csv(prefix + ".csv");
  csv << "image,tilt_deg,photons,hidden_spheres,mode,status,reason,pairing_correct,identity_correct,wrong_ids,superimposed_ids,guide_rot_deg,guide_mm,axis_deg,entry_exit_mm,"
         "seconds,success,view_dev_true_deg,view_dev_est_deg,fronto_parallel,min_circularity,tie_spread_deg\n";
  int image = 0;
  for (double tilt : tilts)
    for (int k = 0; k < per_tilt; ++k, ++image) {
      DistalRendering r;
      r.blur_sigma_px = 0.3 + 0.5 * u(rng);
      r.photons_per_pixel = photon_levels[size_t(3 * u(rng)) % 3];
      r.hidden_spheres = int(9 * u(rng)) % 9;  // 0-8
      r.seed = rng();
      const DistalView v = random_view(rng, tilt, pixels);
      // FLUORO_SWEEP_ONLY=i,j,...: only those images (same draws), written as scenes with
      // FLUORO_SWEEP_DUMP, to look into them.
      if (const char* only = std::getenv("FLUORO_SWEEP_ONLY")) {
        if (("," + std::string(only) + ",").find("," + std::to_string(image) + ",") == std::string::npos) continue;
      }
      const DistalScene s = render_distal_scene(v, r);
      const Image x = log_domain_xray(s.line_integral);
      if (std::getenv("FLUORO_SWEEP_ONLY") && std::getenv("FLUORO_SWEEP_DUMP"))
        write_distal_scene(s, std::string(std::getenv("FLUORO_SWEEP_DUMP")) + "_" + std::to_string(image));
      for (NailMode mode : {NailMode::generic, NailMode::interactive}) {
        BigRow row;
        row.image = image, row.tilt = tilt, row.photons = r.photons_per_pixel, row.hidden = r.hidden_spheres;
        row.mode = mode == NailMode::generic ? "generic" : "interactive";
        row.c = evaluate(s, x, mode);
        // Success: both poses found, the pairing right, what the robot would drill within 1 degree
        // and entry and exit within 1 mm (the goals' means as per-image bounds) for the generic
        // mode; the interactive mode assumes a fronto-parallel view, so its axis is off by the tilt:
        // it is held to the entry and exit bound only.
        row.flagged = !row.c.ok;
        row.success = row.c.ok && row.c.pairing_correct && row.c.entry_exit_mm <= 1.0 &&
                      (mode == NailMode::interactive || row.c.axis_deg <= 1.0);
        row.wrong = row.c.ok && !row.success;
        rows.push_back(row);
        csv << row.image << ',' << tilt << ',' << row.photons << ',' << row.hidden << ',' << row.mode << ','
            << (row.c.ok ? "ok" : "failed") << ",\"" << row.c.reason << "\"," << row.c.pairing_correct << ',' << row.c.identity_correct << ',' << row.c.wrong_ids << ',' << row.c.superimposed_ids << ',' << row.c.guide_rot_deg << ','
            << row.c.guide_trans_mm << ',' << row.c.axis_deg << ',' << row.c.entry_exit_mm << ',' << row.c.seconds << ','
            << row.success << ',' << row.c.view_dev_true << ',' << row.c.view_dev_est << ',' << row.c.fronto_parallel << ','
            << row.c.min_circularity << ',' << row.c.tie_spread_deg << '\n';
        if (std::getenv("FLUORO_SWEEP_DUMP") && row.wrong)
          write_distal_scene(s, std::string(std::getenv("FLUORO_SWEEP_DUMP")) + "_" + std::to_string(image));
      }
      std::fprintf(stderr, "\r%d images", image + 1);
    }
  std::fprintf(stderr, "\n");
  // Per tilt and mode: success rate, flagged (status failed) and wrong (reported but beyond the
  // bounds), the mean and 90th percentile of the axis error, the mean entry/exit error.
  std::printf("# big sweep: %d images per tilt, %dx%d, blur 0.3-0.8 px, photons 5000/20000/80000, 0-8 guide spheres hidden\n",
              per_tilt, pixels, pixels);
  std::printf("| mode | tilt (deg) | images | success | flagged (failed) | wrong | axis (deg, mean) | axis p90 | entry/exit (mm, mean) | entry/exit p90 | time (s, median) |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::map<std::string, std::vector<Series>> curves;
  const auto pct = [](std::vector<double> v, double q) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, size_t(q * double(v.size())))];
  };
  for (const char* mode : {"generic", "interactive"}) {
    Series success{std::string(mode) + " success %", std::strcmp(mode, "generic") == 0 ? "#1a7f37" : "#cf222e", {}, std::strcmp(mode, "generic") != 0};
    Series axis_mean{std::string(mode) + " mean", success.colour, {}, success.dashed}, axis_p90{std::string(mode) + " p90", "#888", {}, success.dashed};
    Series ee_mean = axis_mean, ee_p90 = axis_p90;
    int all = 0, all_success = 0, all_flagged = 0, all_wrong = 0;
    std::vector<double> all_axis, all_ee;
    for (double tilt : tilts) {
      std::vector<double> axis, ee, times;
      int n = 0, ok = 0, flagged = 0, wrong = 0;
      for (const BigRow& r : rows) {
        if (r.tilt != tilt || std::strcmp(r.mode, mode) != 0) continue;
        ++n, ok += r.success, flagged += r.flagged, wrong += r.wrong;
        times.push_back(r.c.seconds);
        if (r.c.ok) axis.push_back(r.c.axis_deg), ee.push_back(r.c.entry_exit_mm);
      }
      const double am = axis.empty() ? 0 : std::accumulate(axis.begin(), axis.end(), 0.0) / double(axis.size());
      const double em = ee.empty() ? 0 : std::accumulate(ee.begin(), ee.end(), 0.0) / double(ee.size());
      std::printf("| %s | %.1f | %d | %.3f | %d | %d | %.3f | %.3f | %.3f | %.3f | %.3f |\n", mode, tilt, n, double(ok) / n, flagged, wrong, am,
                  pct(axis, 0.9), em, pct(ee, 0.9), pct(times, 0.5));
      success.points.push_back({tilt, 100.0 * ok / n});
      axis_mean.points.push_back({tilt, am}), axis_p90.points.push_back({tilt, pct(axis, 0.9)});
      ee_mean.points.push_back({tilt, em}), ee_p90.points.push_back({tilt, pct(ee, 0.9)});
      all += n, all_success += ok, all_flagged += flagged, all_wrong += wrong;
      all_axis.insert(all_axis.end(), axis.begin(), axis.end());
      all_ee.insert(all_ee.end(), ee.begin(), ee.end());
    }
    std::printf("| %s | all | %d | %.3f | %d | %d | %.3f | %.3f | %.3f | %.3f | |\n", mode, all, double(all_success) / all, all_flagged,
                all_wrong, all_axis.empty() ? 0 : std::accumulate(all_axis.begin(), all_axis.end(), 0.0) / double(all_axis.size()),
                pct(all_axis, 0.9), all_ee.empty() ? 0 : std::accumulate(all_ee.begin(), all_ee.end(), 0.0) / double(all_ee.size()),
                pct(all_ee, 0.9));
    curves["success"].push_back(success);
    curves["axis"].push_back(axis_mean), curves["axis"].push_back(axis_p90);
    curves["entry"].push_back(ee_mean), curves["entry"].push_back(ee_p90);
  }
  // The guide's pairing (the same in both modes: the generic rows): by the strict 2 px test and by
  // identity, over the images where it reported a pairing and over all.
  {
    int n = 0, found = 0, strict = 0, identity = 0, blobs = 0;
    for (const BigRow& r : rows) {
      if (std::strcmp(r.mode, "generic") != 0) continue;
      ++n;
      found += r.c.guide_ok;
      strict += r.c.guide_ok && r.c.pairing_correct;
      identity += r.c.guide_ok && r.c.identity_correct;
      blobs += r.c.guide_ok && !r.c.identity_correct && r.c.wrong_ids == r.c.superimposed_ids;
    }
    std::printf("pairing: %d of %d images paired; within 2 px of the truth in %d (%.1f %%), identity correct in %d (%.1f %%) "
                "of those; identity correct in %.1f %% of all %d\n",
                found, n, strict, 100.0 * strict / std::max(1, found), identity, 100.0 * identity / std::max(1, found),
                100.0 * identity / std::max(1, n), n);
    std::printf("pairing: %d more images whose only wrong identities are blobs of two superimposed spheres paired with the "
                "farther one: identity correct up to those in %d of %d (%.1f %%)\n",
                blobs, identity + blobs, found, 100.0 * (identity + blobs) / std::max(1, found));
  }
  // The interactive mode where it is meant to be used: the views it accepts as fronto-parallel
  // (its own estimate of the hole axes' angle to the ray through the nail within
  // kFrontoParallelDeg), and those whose holes' circularity is at least 0.95, next to all views;
  // the generic mode on the same views.
  {
    const auto summary = [&](const char* mode, const char* label, const std::function<bool(const BigRow&)>& accept) {
      std::vector<double> axis, ee, dev;
      int reported = 0;
      for (const BigRow& r : rows) {
        if (std::strcmp(r.mode, mode) != 0 || !r.c.ok) continue;
        ++reported;
        if (!accept(r)) continue;
        axis.push_back(r.c.axis_deg), ee.push_back(r.c.entry_exit_mm), dev.push_back(r.c.view_dev_true);
      }
      const auto mean = [](const std::vector<double>& v) { return v.empty() ? 0.0 : std::accumulate(v.begin(), v.end(), 0.0) / double(v.size()); };
      std::printf("| %s | %s | %zu of %d | %.2f | %.3f | %.3f | %.3f | %.3f |\n", mode, label, axis.size(), reported, dev.empty() ? 0.0 : *std::max_element(dev.begin(), dev.end()),
                  mean(axis), pct(axis, 0.9), mean(ee), pct(ee, 0.9));
    };
    std::printf("\n| mode | views | images (of reported) | true view deviation max (deg) | axis (deg, mean) | axis p90 | entry/exit (mm, mean) | entry/exit p90 |\n");
    std::printf("|---|---|---|---|---|---|---|---|\n");
    for (const char* mode : {"interactive", "generic"}) {
      summary(mode, "all", [](const BigRow&) { return true; });
      summary(mode, "accepted (view deviation <= 1 deg)", [](const BigRow& r) { return r.c.fronto_parallel; });
      summary(mode, "circularity >= 0.95", [](const BigRow& r) { return r.c.min_circularity >= 0.95; });
      summary(mode, "tilt 0", [](const BigRow& r) { return r.tilt == 0; });
    }
  }
  std::ostringstream svg;
  svg << "<svg xmlns='http://www.w3.org/2000/svg' width='720' height='700' viewBox='0 0 720 700'>\n"
      << "<rect width='100%' height='100%' fill='white'/>\n";
  svg_panel(svg, 40, "success rate (%)", curves["success"], 15, 100, "tilt of the hole axes from the ray through the nail (deg)");
  // The interactive mode's axis error is its tilt by construction: only the generic mode's here.
  svg_panel(svg, 270, "hole axis error (deg), generic mode", {curves["axis"][0], curves["axis"][1]}, 15, 1.0,
            "tilt (deg)");
  svg_panel(svg, 500, "entry/exit error (mm)", curves["entry"], 15, 2.0, "tilt (deg)");
  svg << "</svg>\n";
  std::ofstream(prefix + ".svg") << svg.str();
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
  if (argc > 1 && std::strcmp(argv[1], "--bitangent") == 0)
    return bitangent_table(argc > 2 ? std::atoi(argv[2]) : 6, argc > 3 ? std::atoi(argv[3]) : 512, argc > 4 ? std::atof(argv[4]) : 20000);
  if (argc > 4 && std::strcmp(argv[1], "--big-sweep") == 0) return big_sweep(std::atoi(argv[2]), std::atoi(argv[3]), argv[4]);
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
