#include "engine/random_draws.hpp"
#include "datasets/calibration_phantom.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>

#include <opencv2/imgproc.hpp>

#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "engine/pose.hpp"
#include <tbb/parallel_for.h>

namespace fluoro {
namespace {

// A ball on a regular hexagonal step: `across_flats_mm` / 2 is the face's distance from the axis;
// the ball sits just inside the face at angle `deg`, at height z.
Fiducial hex_ball(const std::string& id, double across_mm, double deg, double z) {
  // Distance of a hexagon face from the axis along direction deg (faces normal at 0, 60, ...).
  const double a = radians(deg);
  const double off = std::fmod(std::fmod(deg, 60.0) + 60.0, 60.0);
  const double face = 0.5 * across_mm / std::cos(radians(off > 30 ? 60 - off : off));
  const double r = face - 6.0;  // 6 mm inside the wall
  return {id, Eigen::Vector3d(r * std::cos(a), r * std::sin(a), z)};
}

struct Sphere {
  Eigen::Vector3d c;  // camera frame
  double r;
};
struct Wire {
  Eigen::Vector3d a, w;  // a point and unit direction, camera frame
  double r;
};

// Chord of the ray from the origin along unit d through a sphere; 0 when it misses.
double sphere_chord(const Sphere& s, const Eigen::Vector3d& d) {
  const double along = s.c.dot(d);
  const double perp2 = s.c.squaredNorm() - along * along;
  const double h2 = s.r * s.r - perp2;
  return (h2 > 0 && along > 0) ? 2.0 * std::sqrt(h2) : 0.0;
}

// Chord of the ray through an infinite cylinder: the ray's distance from the axis is measured in
// the plane normal to both; the chord across the cylinder is stretched by 1 / sin(angle).
double wire_chord(const Wire& w, const Eigen::Vector3d& d) {
  const Eigen::Vector3d n = d.cross(w.w);
  const double s = n.norm();
  if (s < 1e-9) return 0.0;
  const double dist = std::abs(w.a.dot(n)) / s;
  const double h2 = w.r * w.r - dist * dist;
  return h2 > 0 ? 2.0 * std::sqrt(h2) / s : 0.0;
}

}  // namespace

PhantomModel tower_phantom() {
  PhantomModel p;
  p.fiducial_diameter_mm = 5.0;
  // Angles chosen by hand: no two steps share a pattern, and no rotation or mirror maps the set
  // onto itself, so the pairing follows from the image alone.
  const double low[] = {0, 75, 160, 250}, mid[] = {35, 130, 200, 310}, top[] = {55, 170, 265, 325};
  for (int i = 0; i < 4; ++i) p.fiducials.push_back(hex_ball("L" + std::to_string(i + 1), 140, low[i], 15));
  for (int i = 0; i < 4; ++i) p.fiducials.push_back(hex_ball("M" + std::to_string(i + 1), 100, mid[i], 100));
  for (int i = 0; i < 4; ++i) p.fiducials.push_back(hex_ball("T" + std::to_string(i + 1), 60, top[i], 185));
  return p;
}

PhantomModel ring_phantom() {
  PhantomModel p;
  p.fiducial_diameter_mm = 4.0;
  // Irregular angles: a regular spacing disturbed by a fixed, aperiodic offset (never more than
  // 9 degrees, so neighbours stay apart).
  for (int k = 0; k < 14; ++k) {
    const double deg = 360.0 * k / 14 + 9.0 * std::sin(2.3 * k + 0.7);
    p.fiducials.push_back({"A" + std::to_string(k + 1),
                           Eigen::Vector3d(90 * std::cos(radians(deg)), 90 * std::sin(radians(deg)), 10)});
  }
  for (int k = 0; k < 12; ++k) {
    const double deg = 360.0 * k / 12 + 11.0 * std::sin(1.7 * k + 2.1) + 7;
    p.fiducials.push_back({"B" + std::to_string(k + 1),
                           Eigen::Vector3d(65 * std::cos(radians(deg)), 65 * std::sin(radians(deg)), 110)});
  }
  return p;
}

PinholeCamera phantom_view_camera(const PhantomView& v) {
  // Camera frame: source at the origin, z towards the detector. The phantom's axis points back at
  // the source, so its frame is turned by 180 degrees about x, then turned about its axis, then tilted.
  const Eigen::Matrix3d flip = Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(radians(v.axis_turn_deg), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Vector3d tilt_axis(-std::sin(radians(v.tilt_azimuth_deg)), std::cos(radians(v.tilt_azimuth_deg)), 0);
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(radians(v.tilt_deg), tilt_axis).toRotationMatrix();
  PinholeCamera c;
  c.width = c.height = v.pixels;
  c.R = tilt * flip * turn;
  c.t = Eigen::Vector3d(v.shift_mm.x(), v.shift_mm.y(), v.source_to_detector_mm - v.base_above_detector_mm);
  const double f = v.source_to_detector_mm / v.pixel_mm;
  const double cx = (v.pixels - 1) * 0.5 + v.principal_offset_px.x();
  const double cy = (v.pixels - 1) * 0.5 + v.principal_offset_px.y();
  c.K << f, 0, cx, 0, f, cy, 0, 0, 1;
  c.pixel_spacing_mm = Eigen::Vector2d(v.pixel_mm, v.pixel_mm);
  return c;
}

CalibrationScene render_calibration_scene(const PhantomModel& phantom, const PhantomView& view,
                                          const XrayRendering& r) {
  CalibrationScene scene;
  scene.camera = phantom_view_camera(view);
  scene.phantom = phantom;
  const PinholeCamera& cam = scene.camera;
  std::mt19937_64 rng(r.seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);

  std::vector<Sphere> spheres;
  const double radius = 0.5 * phantom.fiducial_diameter_mm;
  for (const auto& f : phantom.fiducials) spheres.push_back({cam.R * f.position_mm + cam.t, radius});
  // Clutter balls: inside the phantom's footprint but away from every model ball's image, so the
  // test of rejection is not confounded with overlapping blobs.
  Eigen::Vector3d lo = phantom.fiducials[0].position_mm, hi = lo;
  for (const auto& f : phantom.fiducials) {
    lo = lo.cwiseMin(f.position_mm);
    hi = hi.cwiseMax(f.position_mm);
  }
  for (int k = 0, tries = 0; k < r.clutter_balls && tries < 10000; ++tries) {
    const Eigen::Vector3d r = draw3(uni, rng);
    const Eigen::Vector3d p(lo.x() + r.x() * (hi.x() - lo.x()), lo.y() + r.y() * (hi.y() - lo.y()),
                            lo.z() + r.z() * (hi.z() - lo.z()));
    const Eigen::Vector2d px = cam.project(p);
    bool clear = px.x() > 20 && px.y() > 20 && px.x() < cam.width - 20 && px.y() < cam.height - 20;
    const double min_gap = 4.0 * cam.K(0, 0) * radius / (cam.R * p + cam.t).z();
    for (const auto& s : spheres) {
      const Eigen::Vector3d q = cam.K * s.c;
      if ((q.head<2>() / q.z() - px).norm() < min_gap) clear = false;
    }
    if (!clear) continue;
    spheres.push_back({cam.R * p + cam.t, radius});
    scene.clutter_balls_mm.push_back(p);
    ++k;
  }
  // Clutter wires (1 mm steel) across the field, in the phantom's middle, at random directions.
  std::vector<Wire> wires;
  for (int k = 0; k < r.clutter_wires; ++k) {
    const double a = uni(rng) * std::numbers::pi;
    const Eigen::Vector2d r = draw2(uni, rng);
    const Eigen::Vector3d p(0.3 * (r.x() - 0.5) * (hi.x() - lo.x()), 0.3 * (r.y() - 0.5) * (hi.y() - lo.y()),
                            0.5 * (lo.z() + hi.z()));
    wires.push_back({cam.R * p + cam.t, cam.R * Eigen::Vector3d(std::cos(a), std::sin(a), 0), 0.5});
  }

  const Eigen::Matrix3d Kinv = cam.K.inverse();
  const double f = cam.K(0, 0);
  const int w = cam.width, h = cam.height;
  cv::Mat transmission(h, w, CV_64F);
  const auto mu = r.steel_mu_per_mm;
  tbb::parallel_for(0, h, [&](int v) {
    std::vector<int> near;
    for (int u = 0; u < w; ++u) {
      const Eigen::Vector3d d0 = (Kinv * Eigen::Vector3d(u, v, 1)).normalized();
      // Which primitives can touch this pixel, and is any edge inside it (partial volume)?
      near.clear();
      bool edge = false;
      for (int i = 0; i < int(spheres.size()); ++i) {
        const Sphere& s = spheres[i];
        const double along = s.c.dot(d0);
        const double perp = std::sqrt(std::max(0.0, s.c.squaredNorm() - along * along));
        const double foot = 1.5 * along / f;  // a pixel's half-diagonal at the ball, with margin
        if (perp < s.r + foot) {
          near.push_back(i);
          if (perp > s.r - foot) edge = true;
        }
      }
      bool wire_near = false;
      for (const auto& wi : wires) {
        const Eigen::Vector3d n = d0.cross(wi.w);
        const double dist = std::abs(wi.a.dot(n)) / n.norm();
        const double foot = 1.5 * wi.a.norm() / f / n.norm();
        if (dist < wi.r + foot) wire_near = edge = true;
      }
      if (near.empty() && !wire_near) {
        transmission.at<double>(v, u) = 1.0;
        continue;
      }
      // The detector pixel integrates photons: average exp(-line integral) over its area, finely
      // where an edge crosses it.
      const int n = edge ? 16 : 4;
      double sum = 0;
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          const Eigen::Vector3d d =
              (Kinv * Eigen::Vector3d(u - 0.5 + (i + 0.5) / n, v - 0.5 + (j + 0.5) / n, 1)).normalized();
          double line = 0;
          for (int k : near) line += mu * sphere_chord(spheres[k], d);
          for (const auto& wi : wires) line += mu * wire_chord(wi, d);
          sum += std::exp(-line);
        }
      transmission.at<double>(v, u) = sum / (n * n);
    }
  });
  if (r.blur_sigma_px > 0) cv::GaussianBlur(transmission, transmission, cv::Size(0, 0), r.blur_sigma_px, r.blur_sigma_px, cv::BORDER_REPLICATE);

  scene.line_integral = Image(w, h);
  std::mt19937_64 noise(r.seed * 7919 + 13);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      double t = transmission.at<double>(v, u);
      if (r.photons_per_pixel > 0) {
        std::poisson_distribution<int> counts(r.photons_per_pixel * t);
        // A pixel that caught no photon is read as half a photon: the log stays finite.
        t = std::max(0.5, double(counts(noise))) / r.photons_per_pixel;
      }
      scene.line_integral.at(u, v) = float(-std::log(t));
    }
  return scene;
}

std::vector<uint16_t> log_domain_png_pixels(const Image& line_integral) {
  std::vector<uint16_t> out(line_integral.pixels.size());
  for (size_t i = 0; i < out.size(); ++i)
    out[i] = uint16_t(std::clamp(std::lround(60000.0 - 10000.0 * line_integral.pixels[i]), 0L, 65535L));
  return out;
}

void write_calibration_scene(const CalibrationScene& scene, const std::string& prefix) {
  write_png_u16(log_domain_png_pixels(scene.line_integral), scene.line_integral.width, scene.line_integral.height,
                prefix + ".png");
  write_json(phantom_model_to_json(scene.phantom), prefix + "_phantom.json");
  write_camera(scene.camera, prefix + "_true_camera.json");
}

Image log_domain_xray(const Image& line_integral) {
  Image img(line_integral.width, line_integral.height);
  const auto png = log_domain_png_pixels(line_integral);
  for (size_t i = 0; i < png.size(); ++i) img.pixels[i] = float(png[i]);
  return img;
}

}  // namespace fluoro
