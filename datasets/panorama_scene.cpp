#include "engine/random_draws.hpp"
#include "datasets/panorama_scene.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <opencv2/imgproc.hpp>
#include <random>
#include <stdexcept>

namespace fluoro {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
// Log-domain display: intensity = a - b * line integral, floored where the detector starves
// (behind the clamp), which is what really hides graduations: in an ideal log image a mark under
// metal would still add its contrast.
constexpr double kIntensityA = 52000, kIntensityB = 9000, kIntensityFloor = 1500;
// Linear attenuations (1/mm) and metal thicknesses folded into mu * thickness.
constexpr double kMuTissue = 0.02, kMuCortex = 0.09, kMuMarrow = 0.022, kMuMetal = 0.6;
constexpr double kRulerMetalMuT = 0.55, kRulerPlasticMuT = 0.05;
constexpr double kThreadHalfWidthMm = 1.5, kMarkWidthMm = 1.0;
constexpr double kRulerLateralMm = 62;   // ruler beside the thigh (bone axis at y = 0)
constexpr double kViewCentreLateralMm = 30;

// Fraction of the pixel footprint [x - d/2, x + d/2] inside [lo, hi]: box anti-aliasing.
double coverage(double lo, double hi, double x, double d) {
  return std::max(0.0, std::min(hi, x + 0.5 * d) - std::max(lo, x - 0.5 * d)) / d;
}

// Chord of the ray s + t d (d unit) through the infinite cylinder of radius r around the line
// p + u a (a unit); 0 when it misses.
double cylinder_chord(const Eigen::Vector3d& s, const Eigen::Vector3d& d, const Eigen::Vector3d& p,
                      const Eigen::Vector3d& a, double r) {
  const Eigen::Vector3d w = s - p;
  const Eigen::Vector3d q = d - d.dot(a) * a, wp = w - w.dot(a) * a;
  const double qq = q.squaredNorm();
  if (qq < 1e-12) return 0;
  const double b = wp.dot(q), c = wp.squaredNorm() - r * r, disc = b * b - qq * c;
  return disc > 0 ? 2 * std::sqrt(disc) / qq : 0;
}

struct Bone {
  double x0, x1;  // ends along world x
  double outer(double x) const {
    if (x <= x0 || x >= x1) return 0;
    const double L = x1 - x0, s = (x - x0) / L;
    // Femur-like: a slightly waisted shaft, a wide proximal end and wider condyles.
    double r = 11.5 + 2.0 * (2 * s - 1) * (2 * s - 1) + 14.0 * std::exp(-std::pow(s / 0.08, 2)) +
               22.0 * std::exp(-std::pow((1 - s) / 0.10, 2));
    const double cap = 8.0, e = std::min(x - x0, x1 - x);  // rounded ends
    if (e < cap) r *= std::sqrt(std::max(0.0, 1 - std::pow((cap - e) / cap, 2)));
    return r;
  }
  double tissue(double x) const { return 46.0 + 8.0 * (x - x0) / (x1 - x0); }
};

struct KWire {
  Eigen::Vector3d p, a;  // a unit, the wire from p - half a to p + half a
  double half;
};

struct Clamp {
  double z0, z1;           // slab depth range
  double xlo, xhi, ylo, yhi;
};

struct World {
  Bone bone;
  double zb, zr;
  double ruler_angle, ruler_origin;  // ruler coordinate a = 0 at ruler_origin (mm along the ruler)
  std::vector<KWire> kwires;
  std::optional<Clamp> clamp;
  Eigen::Vector3d landmarks[2];

  // Ruler coordinates (along, across) of a point of the ruler plane.
  Eigen::Vector2d ruler_coords(double x, double y) const {
    const double c = std::cos(ruler_angle), s = std::sin(ruler_angle);
    const double dy = y - kRulerLateralMm;
    return {x * c + dy * s - ruler_origin, -x * s + dy * c};
  }

  double ruler_mu_t(double x, double y, double footprint) const {
    const Eigen::Vector2d rc = ruler_coords(x, y);
    const double a = rc.x(), b = rc.y();
    if (b < -8 || b > 22) return 0;
    double metal = coverage(-kThreadHalfWidthMm, kThreadHalfWidthMm, b, footprint);
    const long k0 = std::lround(a / 5.0);
    for (long k = k0 - 1; k <= k0 + 1; ++k) {
      const double len = (k % 10 == 0) ? 12.0 : (k % 2 == 0) ? 8.0 : 5.0;
      const double ca = coverage(5.0 * double(k) - 0.5 * kMarkWidthMm, 5.0 * double(k) + 0.5 * kMarkWidthMm, a, footprint);
      const double cb = coverage(kThreadHalfWidthMm, kThreadHalfWidthMm + len, b, footprint);
      metal = std::min(1.0, metal + ca * cb);
    }
    return kRulerMetalMuT * metal + kRulerPlasticMuT * coverage(-6, 20, b, footprint);
  }

  // Line integral along the ray from source s in unit direction d; f the focal length (pixels).
  double line_integral(const Eigen::Vector3d& s, const Eigen::Vector3d& d, double f) const {
    double L = 0;
    // Bone and thigh: cylinders along x, their radii taken where the ray crosses the bone plane.
    const double tb = (zb - s.z()) / d.z();
    const double xb = s.x() + tb * d.x();
    const Eigen::Vector3d axis_p(0, 0, zb), ex(1, 0, 0);
    const double rt = bone.tissue(xb);
    L += kMuTissue * cylinder_chord(s, d, axis_p, ex, rt);
    const double r = bone.outer(xb);
    if (r > 0) {
      const double co = cylinder_chord(s, d, axis_p, ex, r), ci = cylinder_chord(s, d, axis_p, ex, 0.6 * r);
      L += (kMuCortex - kMuTissue) * (co - ci) + (kMuMarrow - kMuTissue) * ci;
    }
    for (const auto& lm : landmarks) {  // tantalum beads marking the landmarks
      const Eigen::Vector3d w = lm - s;
      const double dist2 = (w - w.dot(d) * d).squaredNorm();
      if (dist2 < 1.5 * 1.5) L += kMuMetal * 2 * std::sqrt(1.5 * 1.5 - dist2);
    }
    // Ruler: thin plates, integrals scaled by the ray's obliquity.
    const double tr = (zr - s.z()) / d.z();
    L += ruler_mu_t(s.x() + tr * d.x(), s.y() + tr * d.y(), zr / f) / d.z();
    for (const auto& w : kwires) {
      const double chord = cylinder_chord(s, d, w.p, w.a, 1.0);
      if (chord <= 0) continue;
      const double tz = (w.p.z() - s.z()) / d.z();
      const Eigen::Vector3d hit = s + tz * d;
      if (std::abs((hit - w.p).dot(w.a)) <= w.half) L += kMuMetal * chord;
    }
    if (clamp) {
      const double tc = (0.5 * (clamp->z0 + clamp->z1) - s.z()) / d.z();
      const double fp = 0.5 * (clamp->z0 + clamp->z1) / f;
      const double cov = coverage(clamp->xlo, clamp->xhi, s.x() + tc * d.x(), fp) *
                         coverage(clamp->ylo, clamp->yhi, s.y() + tc * d.y(), fp);
      L += cov * kMuMetal * (clamp->z1 - clamp->z0) / d.z();
    }
    return L;
  }
};

Eigen::Matrix3d rot_z(double a) { return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).toRotationMatrix(); }

// The bone's outline on the side facing +y, as the tangent ray from the source grazes it (the
// apparent contour), projected in camera `cam`.
Eigen::Vector2d outline_pixel(const PinholeCamera& cam, const Bone& bone, double zb, double x) {
  const Eigen::Vector3d src = cam.source();
  const double r = bone.outer(x);
  const Eigen::Vector2d s(src.y(), src.z()), a(0, zb);
  const double d = (a - s).norm(), beta = std::asin(r / d);
  const Eigen::Vector2d u = (a - s) / d;
  const Eigen::Vector2d dir(std::cos(-beta) * u.x() - std::sin(-beta) * u.y(), std::sin(-beta) * u.x() + std::cos(-beta) * u.y());
  const Eigen::Vector2d tangent = s + d * std::cos(beta) * dir;
  return cam.project(Eigen::Vector3d(x, tangent.x(), tangent.y()));
}

}  // namespace

Eigen::Vector2d project_in_frame(const PanoramaScene& scene, int frame, const Eigen::Vector3d& x) {
  return scene.cameras.at(size_t(frame)).project(x);
}

PanoramaScene make_panorama_scene(const PanoramaSceneParams& p) {
  if (p.frames < 2 || p.pixels < 64) throw std::invalid_argument("panorama scene: at least 2 frames of 64 px");
  std::mt19937 rng(p.seed);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  PanoramaScene scene;
  const int n = p.pixels;
  const double f = p.source_to_detector_mm / (p.detector_mm / n);
  const double cxy = 0.5 * (n - 1);
  const double fov_r = 0.47 * n;
  World w;
  w.zb = p.bone_plane_mm;
  w.zr = p.bone_plane_mm + p.ruler_offset_mm;
  scene.bone_plane_mm = w.zb;
  scene.ruler_plane_mm = w.zr;
  scene.focal_px = f;
  // Frame spacing from the overlap in the ruler's plane, where the method aligns.
  const double fov_ruler_mm = 2 * fov_r * w.zr / f;
  const double step = (1 - p.overlap) * fov_ruler_mm;
  std::vector<double> xs(size_t(p.frames));
  for (int i = 0; i < p.frames; ++i) {
    xs[size_t(i)] = (i - 0.5 * (p.frames - 1)) * step + p.along_jitter_mm * uni(rng);
    if (p.gap_after_frame >= 0 && i > p.gap_after_frame) xs[size_t(i)] += p.overlap * fov_ruler_mm + 12.0;
  }
  if (p.gap_after_frame >= 0)  // keep the set centred on the bone
    for (auto& x : xs) x -= 0.5 * (p.overlap * fov_ruler_mm + 12.0);
  const double half = 0.5 * p.landmark_distance_mm;
  const double reach = 0.8 * fov_r * w.zb / f;  // landmarks well inside the first and last fields
  if (xs.front() - reach > -half - 5 || xs.back() + reach < half + 5)
    throw std::invalid_argument("panorama scene: the frames do not cover the landmarks");
  w.bone = {-half - 30.0, half + 30.0};
  w.landmarks[0] = Eigen::Vector3d(-half, 0, w.zb);
  w.landmarks[1] = Eigen::Vector3d(half, 0, w.zb);
  w.ruler_angle = p.ruler_angle_deg * kDeg;
  w.ruler_origin = 5.0 * (0.5 + 0.5 * uni(rng));
  scene.landmarks[0] = w.landmarks[0];
  scene.landmarks[1] = w.landmarks[1];
  scene.true_length_mm = (w.landmarks[1] - w.landmarks[0]).norm();

  int clamp_frame = -1;
  if (p.occluders) {
    // K-wires crossing the ruler between it and the source, and a clamp over half of one field.
    for (int k = 0; k < 3; ++k) {
      const double x = xs[size_t((k * 2 + 1) % p.frames)] + 30 * uni(rng);
      const double ang = (35 + 25 * uni(rng)) * kDeg * (k % 2 ? 1 : -1);
      w.kwires.push_back({Eigen::Vector3d(x, kRulerLateralMm, w.zr - 15), Eigen::Vector3d(std::cos(ang), std::sin(ang), 0), 70});
    }
    clamp_frame = p.frames / 2;
    const double zc = w.zr - 40, scale = zc / w.zr;  // its shadow on the ruler covers ~60 mm
    const double xc = xs[size_t(clamp_frame)];
    w.clamp = Clamp{zc, zc + 10, (xc + 2) * scale, (xc + 52) * scale, (kRulerLateralMm - 12) * scale,
                    (kRulerLateralMm + 30) * scale};
  }

  for (int i = 0; i < p.frames; ++i) {
    PinholeCamera cam;
    cam.width = cam.height = n;
    cam.K << f, 0, cxy, 0, f, cxy, 0, 0, 1;
    const double rot = p.max_rotation_deg * uni(rng);
    cam.R = rot_z(rot * kDeg);
    const Eigen::Vector3d src(xs[size_t(i)], kViewCentreLateralMm + p.lateral_jitter_mm * uni(rng), 0);
    cam.t = -cam.R * src;
    scene.cameras.push_back(cam);
    scene.rotation_deg.push_back(rot);
  }

  const double blur = p.blur_px * n / 512.0;
  for (int i = 0; i < p.frames; ++i) {
    const PinholeCamera& cam = scene.cameras[size_t(i)];
    const Eigen::Vector3d src = cam.source();
    cv::Mat img(n, n, CV_32F);
    tbb::parallel_for(tbb::blocked_range<int>(0, n), [&](const tbb::blocked_range<int>& rows) {
      for (int v = rows.begin(); v < rows.end(); ++v)
        for (int u = 0; u < n; ++u) {
          const double L = w.line_integral(src, cam.ray_direction(u, v), f);
          img.at<float>(v, u) = float(std::max(kIntensityFloor, kIntensityA - kIntensityB * L));
        }
    });
    if (blur > 0) cv::GaussianBlur(img, img, cv::Size(0, 0), blur);
    std::normal_distribution<float> noise(0.f, float(p.noise));
    ImageU16 out(n, n);
    for (int v = 0; v < n; ++v)
      for (int u = 0; u < n; ++u) {
        // Circular field of view with a one-pixel soft edge, black outside.
        const double r = std::hypot(u - cxy, v - cxy);
        const double inside = std::clamp(fov_r - r + 0.5, 0.0, 1.0);
        const double value = inside * (img.at<float>(v, u) + (p.noise > 0 ? noise(rng) : 0.f));
        out.at(u, v) = uint16_t(std::clamp(std::lround(value), 0L, 65535L));
      }
    scene.images.push_back(std::move(out));
  }

  if (clamp_frame >= 0) {  // graduations of the clamp's frame inside the field, and those it hides
    const PinholeCamera& cam = scene.cameras[size_t(clamp_frame)];
    int seen = 0, hidden = 0;
    for (int k = -200; k <= 200; ++k) {
      const double a = 5.0 * k + w.ruler_origin, b = kThreadHalfWidthMm + 2.5;
      const double c = std::cos(w.ruler_angle), s = std::sin(w.ruler_angle);
      const Eigen::Vector3d x(a * c - b * s, kRulerLateralMm + a * s + b * c, w.zr);
      const Eigen::Vector2d px = cam.project(x);
      if ((px - Eigen::Vector2d(cxy, cxy)).norm() > fov_r - 5) continue;
      ++seen;
      const Eigen::Vector3d d = (x - cam.source()).normalized();
      const double tc = (0.5 * (w.clamp->z0 + w.clamp->z1) - cam.source().z()) / d.z();
      const Eigen::Vector3d hit = cam.source() + tc * d;
      if (hit.x() > w.clamp->xlo && hit.x() < w.clamp->xhi && hit.y() > w.clamp->ylo && hit.y() < w.clamp->yhi) ++hidden;
    }
    scene.clamp_hidden_fraction = seen ? double(hidden) / seen : 0;
  }

  // The contour for realignment: the bone's outline on the consecutive pair whose shared field
  // shows the most change of radius (a straight edge along the translation says nothing about it).
  // Only the outline's stretches steeper than 10 deg to the bone's axis say something along it.
  // Where no shared field has such a stretch, the pair with the most slope along its shared outline
  // (never a pair that shares no outline at all: that would be an empty trace).
  const double trace_reach = 0.92 * fov_r * w.zb / f;
  double best = -1, best_slope = 0;
  for (int i = 0; i + 1 < p.frames; ++i) {
    const double lo = xs[size_t(i + 1)] - trace_reach, hi = xs[size_t(i)] + trace_reach;
    double change = 0, slope = 0;
    for (double x = std::max(lo, w.bone.x0 + 12); x < std::min(hi, w.bone.x1 - 12); x += 1.0) {
      const double dr = std::abs(w.bone.outer(x + 0.5) - w.bone.outer(x - 0.5));
      change += dr > std::tan(10 * kDeg);
      slope += dr;
    }
    if (change > best || (change == 0 && best == 0 && slope > best_slope))
      best = change, best_slope = slope, scene.contour_first_frame = i;
  }
  const int c0 = scene.contour_first_frame;
  std::normal_distribution<double> trace(0.0, 0.3);
  for (int k = 0; k < 2; ++k) {
    const PinholeCamera& cam = scene.cameras[size_t(c0 + k)];
    const double lo = xs[size_t(c0 + 1)] - trace_reach, hi = xs[size_t(c0)] + trace_reach;
    for (double x = lo + 0.15 * k; x < hi; x += 0.3) {  // about a pixel apart, as a livewire trace
      // Not the rounded ends: their outline is not in the axis plane (an oblique ray grazes the
      // end several mm off it), and a user picks a contour that lies in the plane to measure in.
      if (x < w.bone.x0 + 12 || x > w.bone.x1 - 12) continue;
      const Eigen::Vector2d px = outline_pixel(cam, w.bone, w.zb, x);
      if ((px - Eigen::Vector2d(cxy, cxy)).norm() > 0.92 * fov_r) continue;
      scene.contour[k].push_back(px + draw2(trace, rng));
    }
  }
  return scene;
}

}  // namespace fluoro
