// Dewarp-grid X-rays. Each output pixel is traced back through the true distortion to the ideal
// (pinhole) detector, then along the ray to the source through the 7 mm plate: the aluminium path is
// sampled at several depths, so a hole seen obliquely is the lens between its entrance and exit
// circles, and supersampling gives partial-volume edges.
#include "engine/image_mat.hpp"
#include "engine/random_draws.hpp"
#include "datasets/dewarp_grid.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <random>
#include <stdexcept>

#include "engine/image_io.hpp"
#include "engine/json_io.hpp"

namespace fluoro {
namespace {

constexpr double kHoleContrast = 14000;  // log-domain counts between the plate and a hole
// A dense metal bar starves the detector: the log signal sits at the floor whatever lies behind it.
constexpr double kBarLevel = 6000;

Eigen::Matrix2d distortion_jacobian(const IIDistortion& d, const Eigen::Vector2d& p) {
  const double h = 1e-3;
  Eigen::Matrix2d j;
  j.col(0) = (d.distort(p + Eigen::Vector2d(h, 0)) - d.distort(p - Eigen::Vector2d(h, 0))) / (2 * h);
  j.col(1) = (d.distort(p + Eigen::Vector2d(0, h)) - d.distort(p - Eigen::Vector2d(0, h))) / (2 * h);
  return j;
}

// The largest displacement on the FOV circle: the distortion's strength as the issue states it.
double edge_displacement(const IIDistortion& d, const Eigen::Vector2d& centre, double radius) {
  double worst = 0;
  for (int k = 0; k < 90; ++k) {
    const Eigen::Vector2d p = centre + radius * Eigen::Vector2d(std::cos(k * std::numbers::pi / 45), std::sin(k * std::numbers::pi / 45));
    worst = std::max(worst, (d.distort(p) - p).norm());
  }
  return worst;
}

// The distortion of a C-arm at orbit angle `orbit`: the earth's field turns the swirl and the
// decentring with the orientation; the pincushion (the intensifier's curved input face) stays.
IIDistortion distortion_for(const DewarpSceneOptions& o, std::mt19937_64& rng, const Eigen::Vector2d& image_centre,
                            double fov_radius_px) {
  const double orbit = o.orbit_deg * std::numbers::pi / 180;
  std::uniform_real_distribution<double> jitter(-1, 1);
  IIDistortion d;
  d.radius_px = 0.5 * o.size;
  const double shift = 0.006 * o.size;  // ~6 px at 1024
  d.centre_px = image_centre + shift * Eigen::Vector2d(std::cos(1.3 * orbit + 0.4), std::sin(1.3 * orbit + 0.4)) +
                0.002 * o.size * draw2(jitter, rng);
  const double a = 0.02;
  d.k1 = a * (1 + 0.15 * std::cos(orbit) + 0.05 * jitter(rng));
  d.k2 = 0.25 * a;
  d.swirl = 0.4 * a * std::sin(orbit + 0.5) + 0.1 * a * jitter(rng);
  d.p1 = 0.1 * a * std::cos(2 * orbit);
  d.p2 = 0.1 * a * std::sin(2 * orbit);
  // Scale every term so the edge displacement is what was asked (nearly linear: a few rounds).
  const double target = o.edge_displacement_px * o.size / 1024.0;
  if (!(target > 0)) d.k1 = d.k2 = d.swirl = d.p1 = d.p2 = 0;  // an ideal intensifier
  for (int round = 0; round < 4 && target > 0; ++round) {
    const double s = target / edge_displacement(d, image_centre, fov_radius_px);
    d.k1 *= s, d.k2 *= s, d.swirl *= s, d.p1 *= s, d.p2 *= s;
  }
  return d;
}

void check_options(const DewarpSceneOptions& o) {
  if (o.size < 64 || o.size > 8192) throw std::invalid_argument("dewarp scene: size must be 64 to 8192");
  if (!(o.pixel_mm > 0) || !(o.source_to_detector_mm > o.plate_to_detector_mm + o.grid.thickness_mm) ||
      !(o.plate_to_detector_mm > 0.5 * o.grid.thickness_mm))
    throw std::invalid_argument("dewarp scene: bad geometry");
  if (!(o.hidden_fraction >= 0 && o.hidden_fraction < 1)) throw std::invalid_argument("dewarp scene: hidden_fraction in [0, 1)");
  if (!(o.edge_displacement_px >= 0)) throw std::invalid_argument("dewarp scene: edge_displacement_px must be >= 0");
  if (!(o.fov_radius > 0.1 && o.fov_radius <= 0.5)) throw std::invalid_argument("dewarp scene: fov_radius in (0.1, 0.5]");
  if (o.supersampling < 1 || o.supersampling > 8) throw std::invalid_argument("dewarp scene: supersampling 1 to 8");
}

// A dense straight bar in the ideal detector plane (mm): |normal . (x - point)| < half_width.
struct Bar {
  Eigen::Vector2d point{0, 0}, normal{1, 0};
  double half_width = -1;  // negative: no bar
  bool covers(const Eigen::Vector2d& x, double margin = 0) const {
    return half_width >= 0 && std::abs(normal.dot(x - point)) < half_width + margin;
  }
};

}  // namespace

Eigen::Vector2d IIDistortion::distort(const Eigen::Vector2d& ideal) const {
  const Eigen::Vector2d n = (ideal - centre_px) / radius_px;
  const double r2 = n.squaredNorm();
  const Eigen::Vector2d radial = n * (1 + k1 * r2 + k2 * r2 * r2);
  const double a = swirl * r2;
  const Eigen::Vector2d turned(std::cos(a) * radial.x() - std::sin(a) * radial.y(),
                               std::sin(a) * radial.x() + std::cos(a) * radial.y());
  const Eigen::Vector2d tangential(2 * p1 * n.x() * n.y() + p2 * (r2 + 2 * n.x() * n.x()),
                                   p1 * (r2 + 2 * n.y() * n.y()) + 2 * p2 * n.x() * n.y());
  return centre_px + radius_px * (turned + tangential);
}

Eigen::Vector2d IIDistortion::undistort(const Eigen::Vector2d& distorted) const { return undistort(distorted, distorted); }

Eigen::Vector2d IIDistortion::undistort(const Eigen::Vector2d& distorted, const Eigen::Vector2d& guess) const {
  Eigen::Vector2d p = guess;
  for (int it = 0; it < 30; ++it) {
    const Eigen::Vector2d f = distort(p) - distorted;
    if (f.norm() < 1e-10) break;
    p -= distortion_jacobian(*this, p).inverse() * f;
  }
  return p;
}

DewarpScene make_dewarp_scene(const DewarpSceneOptions& o) {
  check_options(o);
  std::mt19937_64 rng(o.seed * 7919 + 17);
  std::uniform_real_distribution<double> uni(-1, 1);
  DewarpScene s;
  s.grid = o.grid;
  const double scale = 1024.0 / o.size;
  const double pixel_mm = o.pixel_mm * scale;
  const double blur = o.blur_sigma_px / scale;
  const double H = o.source_to_detector_mm, h = o.plate_to_detector_mm, t = o.grid.thickness_mm;
  const Eigen::Vector2d image_centre(0.5 * (o.size - 1), 0.5 * (o.size - 1));
  // Principal point (foot of the source) a little off the image centre.
  const Eigen::Vector2d pp = image_centre + 0.004 * o.size * draw2(uni, rng);
  s.fov_centre_px = image_centre;
  s.fov_radius_px = o.fov_radius * o.size;
  s.distortion = distortion_for(o, rng, image_centre, s.fov_radius_px);

  // Plate pose on the intensifier face: a small turn and offset (it is screwed on by hand).
  const double magnification = H / (H - h);
  const Eigen::Matrix2d plate_rot = Eigen::Rotation2Dd((2.0 + uni(rng)) * std::numbers::pi / 180).toRotationMatrix();
  const Eigen::Vector2d plate_offset_mm = 2.0 * draw2(uni, rng);
  s.plate_to_ideal = magnification / pixel_mm * plate_rot;
  s.plate_origin_px = pp + magnification / pixel_mm * plate_offset_mm;
  const double hole_radius_mm = 0.5 * o.grid.hole_diameter_mm;
  const double hole_radius_px = hole_radius_mm * s.px_per_plate_mm();

  // Holes inside the FOV, before the occluder.
  const Eigen::Matrix2d ideal_to_plate = s.plate_to_ideal.inverse();
  const double edge_margin = hole_radius_px + 3 * blur + 1.5;
  for (int r = 0; r < o.grid.rows; ++r)
    for (int c = 0; c < o.grid.cols; ++c) {
      DewarpTruthHole hole;
      hole.row = r, hole.col = c;
      hole.ideal_px = s.ideal_of_plate(o.grid.hole_mm(r, c));
      hole.distorted_px = s.distortion.distort(hole.ideal_px);
      const double from_centre = (hole.distorted_px - s.fov_centre_px).norm();
      if (from_centre > s.fov_radius_px + hole_radius_px) continue;
      hole.visible = from_centre < s.fov_radius_px - edge_margin;
      s.holes.push_back(hole);
    }

  // The occluder: a bar whose width is searched so it hides the asked fraction of the FOV's holes.
  Bar bar;
  const double hole_margin_mm = (hole_radius_px + 2 * blur + 1) * pixel_mm;
  auto ideal_mm = [&](const Eigen::Vector2d& ideal_px) -> Eigen::Vector2d { return (ideal_px - pp) * pixel_mm; };
  int inside = 0;
  for (const auto& hole : s.holes) inside += hole.visible;
  auto hidden_by = [&](const Bar& b) {
    int n = 0;
    for (const auto& hole : s.holes) n += hole.visible && b.covers(ideal_mm(hole.ideal_px), hole_margin_mm);
    return n;
  };
  if (o.hidden_fraction > 0 && inside > 0) {
    const double angle = std::numbers::pi * (0.5 + 0.5 * uni(rng));
    bar.normal = Eigen::Vector2d(std::cos(angle), std::sin(angle));
    bar.point = bar.normal * (0.25 * s.fov_radius_px * pixel_mm * uni(rng));
    double lo = 0, hi = 2 * s.fov_radius_px * pixel_mm;
    for (int it = 0; it < 40; ++it) {
      bar.half_width = 0.5 * (lo + hi);
      (hidden_by(bar) < o.hidden_fraction * inside ? lo : hi) = bar.half_width;
    }
    bar.half_width = hi;
  }
  int hidden = 0;
  for (auto& hole : s.holes)
    if (hole.visible && bar.covers(ideal_mm(hole.ideal_px), hole_margin_mm)) hole.visible = false, ++hidden;
  s.hidden_fraction = inside > 0 ? double(hidden) / inside : 0;

  // Render: every pixel traced back through the distortion; sub-samples through the local Jacobian.
  const int n = o.size, ss = o.supersampling;
  cv::Mat img(n, n, CV_64F, cv::Scalar(0));
  const double shift_max = 0.5 * t * (s.fov_radius_px * 1.5 * pixel_mm) / H + 0.05;
  tbb::parallel_for(0, n, [&](int v) {
    Eigen::Vector2d guess(0, v);
    bool have_guess = false;
    for (int u = 0; u < n; ++u) {
      const Eigen::Vector2d d(u, v);
      if ((d - s.fov_centre_px).norm() > s.fov_radius_px + 1) {
        have_guess = false;
        continue;
      }
      const Eigen::Vector2d p0 = s.distortion.undistort(d, have_guess ? guess : d);
      guess = p0, have_guess = true;
      const Eigen::Matrix2d jinv = distortion_jacobian(s.distortion, p0).inverse();
      double sum = 0;
      for (int sy = 0; sy < ss; ++sy)
        for (int sx = 0; sx < ss; ++sx) {
          const Eigen::Vector2d off((sx + 0.5) / ss - 0.5, (sy + 0.5) / ss - 0.5);
          if ((d + off - s.fov_centre_px).norm() > s.fov_radius_px) continue;
          const Eigen::Vector2d x_mm = ideal_mm(p0 + jinv * off);
          // Aluminium path: sample the ray at depths through the plate; a hole is a cylinder.
          const Eigen::Vector2d q_mid = ideal_to_plate * (p0 + jinv * off - s.plate_origin_px);
          const double col = std::round(q_mid.x() / o.grid.pitch_mm + 0.5 * (o.grid.cols - 1));
          const double row = std::round(q_mid.y() / o.grid.pitch_mm + 0.5 * (o.grid.rows - 1));
          const bool on_plate = row >= 0 && row < o.grid.rows && col >= 0 && col < o.grid.cols;
          double open = 0;  // fraction of the plate's thickness the ray spends inside a hole
          if (on_plate) {
            const Eigen::Vector2d hc = o.grid.hole_mm(row, col);
            if ((q_mid - hc).norm() < hole_radius_mm + shift_max) {
              constexpr int depths = 8;
              for (int k = 0; k < depths; ++k) {
                const double z = h - 0.5 * t + (k + 0.5) * t / depths;
                const Eigen::Vector2d world = x_mm * (1 - z / H);
                const Eigen::Vector2d q = plate_rot.transpose() * (world - plate_offset_mm);
                open += (q - hc).squaredNorm() < hole_radius_mm * hole_radius_mm;
              }
              open /= depths;
            }
          }
          const double secant = std::sqrt(x_mm.squaredNorm() + H * H) / H;
          const double al = on_plate ? (1 - open) * secant : 0;
          const double rx = x_mm.x() / 200, rr = x_mm.squaredNorm() / (200.0 * 200.0);
          double value = 42000 + 2500 * rx - 4000 * rr - kHoleContrast * al;  // heel effect, vignetting
          if (bar.covers(x_mm)) value = kBarLevel;
          sum += value;
        }
      img.at<double>(v, u) = sum / (ss * ss);
    }
  });

  // Dust on the intensifier's screen: small blobs, bright and dark, in the distorted image.
  for (int k = 0; k < o.dust_count; ++k) {
    const double a = std::numbers::pi * uni(rng), rad = s.fov_radius_px * std::sqrt(0.5 + 0.5 * uni(rng)) * 0.95;
    const Eigen::Vector2d c = s.fov_centre_px + rad * Eigen::Vector2d(std::cos(2 * a), std::sin(2 * a));
    const double sigma = (0.9 + 0.6 * (1 + uni(rng))) / scale;
    const double amp = kHoleContrast * (0.4 + 0.3 * (1 + uni(rng))) * (k % 3 == 2 ? -1 : 1);
    const int r = int(std::ceil(4 * sigma));
    for (int v = std::max(0, int(c.y()) - r); v <= std::min(n - 1, int(c.y()) + r); ++v)
      for (int u = std::max(0, int(c.x()) - r); u <= std::min(n - 1, int(c.x()) + r); ++u)
        if (img.at<double>(v, u) > 0)
          img.at<double>(v, u) += amp * std::exp(-((u - c.x()) * (u - c.x()) + (v - c.y()) * (v - c.y())) / (2 * sigma * sigma));
  }

  if (blur > 0) cv::GaussianBlur(img, img, cv::Size(0, 0), blur, blur, cv::BORDER_REPLICATE);
  std::normal_distribution<double> gauss(0, o.noise_sigma * kHoleContrast);
  s.image = Image(n, n);
  for (int v = 0; v < n; ++v)
    for (int u = 0; u < n; ++u) {
      const bool in_fov = (Eigen::Vector2d(u, v) - s.fov_centre_px).norm() <= s.fov_radius_px + 0.5;
      double value = img.at<double>(v, u);
      if (in_fov && o.noise_sigma > 0) value += gauss(rng);
      s.image.at(u, v) = float(std::round(std::clamp(in_fov ? value : 0.0, 0.0, 65535.0)));
    }
  return s;
}

DewarpMapError dewarp_map_error(const DewarpScene& s,
                                const std::function<std::optional<Eigen::Vector2d>(const Eigen::Vector2d&)>& correct) {
  std::vector<Eigen::Vector2d> fitted, ideal;
  std::vector<uint8_t> visible(size_t(s.grid.rows) * size_t(s.grid.cols), 0);
  for (const auto& h : s.holes) {
    if (!h.visible) continue;
    visible[size_t(h.row) * size_t(s.grid.cols) + size_t(h.col)] = 1;
    if (const auto c = correct(h.distorted_px)) fitted.push_back(*c), ideal.push_back(h.ideal_px);
  }
  DewarpMapError r;
  if (fitted.size() < 3) return r;
  Eigen::Matrix2Xd from(2, fitted.size()), to(2, fitted.size());
  for (size_t k = 0; k < fitted.size(); ++k) from.col(Eigen::Index(k)) = fitted[k], to.col(Eigen::Index(k)) = ideal[k];
  const Eigen::Matrix3d sim = Eigen::umeyama(from, to, true);
  const double mm_per_px = 1.0 / s.px_per_plate_mm();
  auto vis = [&](int row, int col) { return visible[size_t(row) * size_t(s.grid.cols) + size_t(col)] != 0; };
  auto add = [](DewarpErrorStats& e, double v) { e.mean_mm += v, e.max_mm = std::max(e.max_mm, v), ++e.samples; };
  for (int row = 0; row < s.grid.rows - 1; ++row)
    for (int col = 0; col < s.grid.cols - 1; ++col) {
      const bool between = vis(row, col) && vis(row + 1, col) && vis(row, col + 1) && vis(row + 1, col + 1);
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) {
          const Eigen::Vector2d id = s.ideal_of_plate(s.grid.hole_mm(row + (a + 0.5) / 4, col + (b + 0.5) / 4));
          const Eigen::Vector2d d = s.distortion.distort(id);
          if ((d - s.fov_centre_px).norm() > s.fov_radius_px - 2) continue;
          const auto c = correct(d);
          if (!c) continue;
          const double e = ((sim.topLeftCorner<2, 2>() * *c + sim.topRightCorner<2, 1>()) - id).norm() * mm_per_px;
          add(between ? r.between : r.elsewhere, e);
        }
    }
  for (DewarpErrorStats* e : {&r.between, &r.elsewhere})
    if (e->samples > 0) e->mean_mm /= e->samples;
  return r;
}

void save_dewarp_scene(const DewarpScene& scene, const std::string& image_path, const std::string& grid_path) {
  std::vector<uint16_t> pixels(scene.image.pixels.size());
  for (size_t i = 0; i < pixels.size(); ++i) pixels[i] = uint16_t(scene.image.pixels[i]);
  write_png_u16(pixels, scene.image.width, scene.image.height, image_path);
  write_json(grid_model_to_json(scene.grid), grid_path);
}

Image distort_image(const Image& ideal, const IIDistortion& distortion) {
  cv::Mat map_x(ideal.height, ideal.width, CV_32F), map_y(ideal.height, ideal.width, CV_32F);
  tbb::parallel_for(0, ideal.height, [&](int v) {
    for (int u = 0; u < ideal.width; ++u) {
      const Eigen::Vector2d p = distortion.undistort(Eigen::Vector2d(u, v), Eigen::Vector2d(u, v));
      map_x.at<float>(v, u) = float(p.x());
      map_y.at<float>(v, u) = float(p.y());
    }
  });
  const cv::Mat src = mat_view(ideal);
  Image out(ideal.width, ideal.height);
  cv::Mat dst = mat_view(out);
  cv::remap(src, dst, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  return out;
}

}  // namespace fluoro
