#include "engine/random_draws.hpp"
#include "datasets/distal_locking_scene.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include <opencv2/imgproc.hpp>
#include <tbb/parallel_for.h>

#include "datasets/calibration_phantom.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "engine/nail_chord.hpp"
#include "engine/pose.hpp"

namespace fluoro {
namespace {

// A uniform number in [0, 1) from the engine's bits alone (std's distributions differ by library).
double uniform(std::mt19937_64& rng) { return double(rng() >> 11) * (1.0 / 9007199254740992.0); }

struct Ball {
  Eigen::Vector3d c;  // camera frame
  double r, mu;
  Eigen::Vector2d px;
  double r_px;
};

double ball_chord(const Ball& b, const Eigen::Vector3d& d) {
  const double along = b.c.dot(d);
  const double h2 = b.r * b.r - (b.c.squaredNorm() - along * along);
  return (h2 > 0 && along > 0) ? 2.0 * std::sqrt(h2) : 0.0;
}

Eigen::Isometry3d isometry(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = t;
  return T;
}

}  // namespace

DrillGuideModel drill_guide_model() {
  DrillGuideModel g;
  g.sphere_diameter_mm = 3.0;
  // Irregular places drawn once from a fixed seed with rejection: at least 7 mm apart on a plane,
  // 6 mm clear of both axes, inside an 84 x 56 mm plate. The same numbers on every platform.
  std::mt19937_64 rng(20261201);
  for (double z : {0.0, 20.0}) {
    std::vector<Eigen::Vector3d> plane;
    while (plane.size() < 14) {
      const Eigen::Vector2d r = draw2(uniform, rng);
      const Eigen::Vector3d p(-42 + 84 * r.x(), -28 + 56 * r.y(), z);
      bool ok = (p.head<2>() - Eigen::Vector2d(-15, 0)).norm() > 6 && (p.head<2>() - Eigen::Vector2d(15, 0)).norm() > 6;
      for (const auto& q : plane) ok = ok && (p - q).norm() >= 7;
      if (ok) plane.push_back(p);
    }
    g.spheres_mm.insert(g.spheres_mm.end(), plane.begin(), plane.end());
  }
  g.axes = {{"proximal", Eigen::Vector3d(-15, 0, 0), Eigen::Vector3d::UnitZ()},
            {"distal", Eigen::Vector3d(15, 0, 0), Eigen::Vector3d::UnitZ()}};
  return g;
}

NailModel nail_model() {
  NailModel n;
  n.diameter_mm = 10.0;
  n.holes = {{Eigen::Vector3d(-15, 0, 0), 5.0}, {Eigen::Vector3d(15, 0, 0), 5.0}};
  return n;
}

DistalScene render_distal_scene(const DistalView& v, const DistalRendering& r) {
  DistalScene s;
  s.guide = drill_guide_model();
  s.nail = nail_model();

  // The camera: a fixed pose in the world, K from the detector.
  PinholeCamera& cam = s.camera;
  cam.width = cam.height = v.pixels;
  const double pixel_mm = v.detector_mm / v.pixels;
  const double f = v.source_to_detector_mm / pixel_mm;
  cam.K << f, 0, (v.pixels - 1) * 0.5 + v.principal_offset_px.x(), 0, f, (v.pixels - 1) * 0.5 + v.principal_offset_px.y(), 0, 0, 1;
  cam.R = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  cam.t = Eigen::Vector3d(12, -25, 40);
  cam.pixel_spacing_mm = Eigen::Vector2d(pixel_mm, pixel_mm);

  // The nail in the camera frame: hole axes along the ray from the source through the nail's
  // centre (away from the source), the long axis across it at the roll angle in the image, then
  // tilted about an in-plane direction of the nail. Tilt 0 is the view the technician aims for,
  // each hole seen through along the ray (the see-through lens is roundest there); it was the
  // central ray, which put views with the nail off the image's centre 0-2.7 degrees off the rays
  // through the holes and showed as the interactive mode's axis error at "tilt 0".
  const Eigen::Vector3d t_cn(v.nail_offset_mm.x(), v.nail_offset_mm.y(), v.nail_depth_mm);
  const Eigen::Vector3d z0 = t_cn.normalized();
  const Eigen::Vector3d roll(std::cos(radians(v.nail_roll_deg)), std::sin(radians(v.nail_roll_deg)), 0);
  const Eigen::Vector3d x0 = (roll - roll.dot(z0) * z0).normalized();
  Eigen::Matrix3d R0;
  R0 << x0, z0.cross(x0), z0;
  const Eigen::Vector3d tilt_axis = std::cos(radians(v.tilt_azimuth_deg)) * R0.col(0) + std::sin(radians(v.tilt_azimuth_deg)) * R0.col(1);
  const Eigen::Matrix3d R_cn = Eigen::AngleAxisd(radians(v.tilt_deg), tilt_axis).toRotationMatrix() * R0;
  // The guide: its axes near the hole axes (misaligned about a fixed oblique direction), on the
  // source's side, its near plane (z = 20) `guide_gap_mm` from the nail's surface.
  const Eigen::Vector3d mis_axis = (R_cn * Eigen::Vector3d(0.6, 0.8, 0)).normalized();
  const Eigen::Matrix3d R_cg = Eigen::AngleAxisd(radians(v.guide_misalignment_deg), mis_axis).toRotationMatrix() * R_cn;
  const double near_plane = 20.0;
  const Eigen::Vector3d t_cg =
      R_cn * (v.guide_offset_mm + Eigen::Vector3d(0, 0, -0.5 * s.nail.diameter_mm - v.guide_gap_mm)) + t_cn -
      R_cg * Eigen::Vector3d(0, 0, near_plane);
  s.T_world_nail = isometry(cam.R.transpose() * R_cn, cam.R.transpose() * (t_cn - cam.t));
  s.T_world_guide = isometry(cam.R.transpose() * R_cg, cam.R.transpose() * (t_cg - cam.t));

  std::mt19937_64 rng(r.seed);
  std::vector<int> ids(s.guide.spheres_mm.size());
  for (size_t i = 0; i < ids.size(); ++i) ids[i] = int(i);
  for (int k = 0; k < r.hidden_spheres && k < int(ids.size()); ++k)
    std::swap(ids[size_t(k)], ids[size_t(k) + size_t(uniform(rng) * double(ids.size() - size_t(k)))]);
  s.hidden_ids.assign(ids.begin(), ids.begin() + std::min<int>(r.hidden_spheres, int(ids.size())));
  std::sort(s.hidden_ids.begin(), s.hidden_ids.end());

  std::vector<Ball> balls;
  const auto add_ball = [&](const Eigen::Vector3d& c, double radius, double mu) {
    const Eigen::Vector3d q = cam.K * c;
    balls.push_back({c, radius, mu, q.head<2>() / q.z(), f * radius / c.z() * 1.05 + 2.0});
  };
  for (int i = 0; i < int(s.guide.spheres_mm.size()); ++i)
    if (!std::binary_search(s.hidden_ids.begin(), s.hidden_ids.end(), i))
      add_ball(R_cg * s.guide.spheres_mm[size_t(i)] + t_cg, 0.5 * s.guide.sphere_diameter_mm, r.steel_mu_per_mm);
  if (r.ring_clutter)  // the ring phantom on the image intensifier, 40 mm above the detector
    for (const auto& fid : ring_phantom().fiducials)
      add_ball(Eigen::Vector3d(fid.position_mm.x(), -fid.position_mm.y(), v.source_to_detector_mm - 40 - fid.position_mm.z()),
               2.0, r.steel_mu_per_mm);

  // The nail's tip 45 mm beyond the distal hole, its shaft past the image; bone and tissue long.
  const PlacedNail nail = place_nail(s.nail, R_cn, t_cn, -400.0, 60.0);
  const Cylinder bone_out{t_cn, R_cn.col(0), 14.0}, bone_in{t_cn, R_cn.col(0), 8.0};
  const Cylinder tissue{t_cn, R_cn.col(0), r.tissue_radius_mm};

  const Eigen::Matrix3d Kinv = cam.K.inverse();
  const int w = cam.width, h = cam.height, n = std::max(1, r.supersampling);
  cv::Mat transmission(h, w, CV_64F);
  tbb::parallel_for(0, h, [&](int row) {
    std::vector<const Ball*> near;
    for (int col = 0; col < w; ++col) {
      near.clear();
      for (const auto& b : balls)
        if ((b.px - Eigen::Vector2d(col, row)).squaredNorm() < b.r_px * b.r_px) near.push_back(&b);
      double sum = 0;
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          const Eigen::Vector3d d =
              (Kinv * Eigen::Vector3d(col - 0.5 + (i + 0.5) / n, row - 0.5 + (j + 0.5) / n, 1)).normalized();
          double line = (r.nail_present ? r.nail_mu_per_mm * nail_chord_mm(nail, d) : 0.0) +
                        r.bone_mu_per_mm * (ray_in_cylinder(bone_out, d).length() - ray_in_cylinder(bone_in, d).length()) +
                        r.tissue_mu_per_mm * ray_in_cylinder(tissue, d).length();
          for (const Ball* b : near) line += b->mu * ball_chord(*b, d);
          sum += std::exp(-line);
        }
      transmission.at<double>(row, col) = sum / (n * n);
    }
  });
  if (r.blur_sigma_px > 0)
    cv::GaussianBlur(transmission, transmission, cv::Size(0, 0), r.blur_sigma_px, r.blur_sigma_px, cv::BORDER_REPLICATE);
  s.line_integral = Image(w, h);
  std::mt19937_64 noise(r.seed * 7919 + 13);
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) {
      double t = transmission.at<double>(row, col);
      if (r.photons_per_pixel > 0) {
        std::poisson_distribution<int> counts(r.photons_per_pixel * t);
        t = std::max(0.5, double(counts(noise))) / r.photons_per_pixel;
      }
      s.line_integral.at(col, row) = float(-std::log(t));
    }
  return s;
}

void write_distal_scene(const DistalScene& s, const std::string& prefix) {
  write_png_u16(log_domain_png_pixels(s.line_integral), s.line_integral.width, s.line_integral.height, prefix + ".png");
  write_camera(s.camera, prefix + "_camera.json");
  write_json(drill_guide_model_to_json(s.guide), prefix + "_guide.json");
  write_json(nail_model_to_json(s.nail), prefix + "_nail.json");
  const auto rows = [](const Eigen::Matrix4d& m) {
    nlohmann::json out = nlohmann::json::array();
    for (int i = 0; i < 4; ++i) out.push_back({m(i, 0), m(i, 1), m(i, 2), m(i, 3)});
    return out;
  };
  write_json({{"T_world_guide", rows(s.T_world_guide.matrix())}, {"T_world_nail", rows(s.T_world_nail.matrix())},
              {"hidden_sphere_ids", s.hidden_ids}},
             prefix + "_truth.json");
}

}  // namespace fluoro
