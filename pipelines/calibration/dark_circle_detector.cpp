#include "pipelines/calibration/dark_circle_detector.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <Eigen/Eigenvalues>
#include <opencv2/imgproc.hpp>

#include "engine/field_of_view.hpp"
#include "engine/image_mat.hpp"

namespace fluoro {
namespace {

constexpr int kSectors = 24;

struct EdgePixel {
  float gx, gy, mag;
};

// Robust noise level of a gradient component: the median absolute value of a flat, noisy
// background is 0.6745 sigma; balls cover too little of the image to move it.
double gradient_noise_sigma(const cv::Mat& gx) {
  std::vector<float> a;
  a.reserve(gx.total() / 4 + 1);
  for (int v = 0; v < gx.rows; v += 2)
    for (int u = 0; u < gx.cols; u += 2) a.push_back(std::abs(gx.at<float>(v, u)));
  if (a.empty()) return 0;
  std::nth_element(a.begin(), a.begin() + a.size() / 2, a.end());
  return 1.4826 * a[a.size() / 2];
}

// The centroid's window: the edge radius plus 1.5 px covers partial volume and a blur of up to
// 1 px; every pixel more adds only noise (on generated images with 150 photons per pixel, R + 3.5
// doubled the calibration's error against R + 1.5).
double window_radius(double radius_px) { return radius_px + 1.5; }

}  // namespace

BlobCentroid dark_blob_centroid(const Image& image, const Eigen::Vector2d& start, double radius_px) {
  const double rw = window_radius(radius_px), rb = rw + 3.0;
  BlobCentroid out{start, 0.0};
  Eigen::Vector2d c = start;
  for (int iter = 0; iter < 3; ++iter) {
    const int u0 = int(std::floor(c.x() - rb)), u1 = int(std::ceil(c.x() + rb));
    const int v0 = int(std::floor(c.y() - rb)), v1 = int(std::ceil(c.y() + rb));
    if (u0 < 0 || v0 < 0 || u1 >= image.width || v1 >= image.height) return out;
    // Background plane a + b du + c dv on the ring outside the window (a Delrin body or a heel
    // effect makes it slope).
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    for (int v = v0; v <= v1; ++v)
      for (int u = u0; u <= u1; ++u) {
        const double du = u - c.x(), dv = v - c.y(), d = std::hypot(du, dv);
        if (d <= rw || d > rb) continue;
        const Eigen::Vector3d x(1, du, dv);
        A += x * x.transpose();
        b += x * image.at(u, v);
      }
    const Eigen::Vector3d plane = A.ldlt().solve(b);
    double sw = 0;
    Eigen::Vector2d sp = Eigen::Vector2d::Zero();
    Eigen::Matrix2d spp = Eigen::Matrix2d::Zero();
    for (int v = v0; v <= v1; ++v)
      for (int u = u0; u <= u1; ++u) {
        const double du = u - c.x(), dv = v - c.y();
        if (std::hypot(du, dv) > rw) continue;
        // Signed weights: clipping at zero would turn the background's noise into a pull
        // towards the window's centre.
        const double wgt = plane(0) + plane(1) * du + plane(2) * dv - image.at(u, v);
        sw += wgt;
        sp += wgt * Eigen::Vector2d(u, v);
        spp += wgt * Eigen::Vector2d(du, dv) * Eigen::Vector2d(du, dv).transpose();
      }
    if (!(sw > 0)) return out;
    const Eigen::Vector2d next = sp / sw;
    if ((next - start).norm() > radius_px) return out;  // drifted onto something else
    // Second moments about the centroid: a ball's image is round, two merged balls are not.
    const Eigen::Vector2d d = next - c;
    const Eigen::Matrix2d m = spp / sw - d * d.transpose();
    const Eigen::Vector2d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(m).eigenvalues();
    out.elongation = ev(0) > 0 ? std::sqrt(ev(1) / ev(0)) : std::numeric_limits<double>::infinity();
    c = next;
  }
  out.centre_px = c;
  return out;
}

std::vector<DarkCircle> detect_dark_circles(const Image& image, const DarkCircleParams& p) {
  std::vector<DarkCircle> out;
  if (image.empty()) return out;
  const int w = image.width, h = image.height;
  const double rmin = std::max(1.0, p.min_radius_px);
  const double rmax = p.max_radius_px > 0 ? p.max_radius_px : std::max(rmin + 1, 0.04 * std::min(w, h));

  cv::Mat img = mat_view(image);
  cv::Mat smooth, gx, gy;
  cv::GaussianBlur(img, smooth, cv::Size(0, 0), p.smoothing_sigma_px, p.smoothing_sigma_px, cv::BORDER_REPLICATE);
  cv::Sobel(smooth, gx, CV_32F, 1, 0, 3, 1.0, 0.0, cv::BORDER_REPLICATE);
  cv::Sobel(smooth, gy, CV_32F, 0, 1, 3, 1.0, 0.0, cv::BORDER_REPLICATE);
  cv::Mat mag;
  cv::magnitude(gx, gy, mag);
  // The strongest edge is looked for inside the field of view, a few pixels in from its rim: the
  // intensifier's black surround (or a collimator) makes far stronger edges than any ball, and
  // faint or small balls would fall under a fraction of those.
  const cv::Mat inside = field_of_view_mask(img, 4);
  double max_mag = 0;
  cv::minMaxLoc(mag, nullptr, &max_mag, nullptr, nullptr, cv::countNonZero(inside) > 0 ? inside : cv::noArray());
  if (!(max_mag > 0)) return out;
  // An edge is well above the noise and not a negligible ripple next to the strongest edge.
  const double threshold = std::max(4.0 * gradient_noise_sigma(gx), 0.05 * max_mag);

  // Votes: a dark disc's gradient points outwards, so its centre lies against the gradient.
  cv::Mat acc = cv::Mat::zeros(h, w, CV_32F);
  std::vector<EdgePixel> edges(size_t(w) * h, EdgePixel{0, 0, 0});
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      const float m = mag.at<float>(v, u);
      if (m < threshold) continue;
      const float ex = gx.at<float>(v, u) / m, ey = gy.at<float>(v, u) / m;
      edges[size_t(v) * w + u] = {ex, ey, m};
      for (double r = rmin; r <= rmax; r += 0.5) {
        const int cu = int(std::lround(u - r * ex)), cv_ = int(std::lround(v - r * ey));
        if (cu >= 0 && cv_ >= 0 && cu < w && cv_ < h) acc.at<float>(cv_, cu) += 1.0f;
      }
    }
  cv::GaussianBlur(acc, acc, cv::Size(0, 0), 1.0);
  cv::Mat dil;
  const int k = 2 * int(std::lround(rmin)) + 1;
  cv::dilate(acc, dil, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k)));
  struct Peak {
    int u, v;
    float votes;
  };
  std::vector<Peak> peaks;
  // A circle of radius r, its edge about 2 px wide, sends about 4 pi r votes into its centre,
  // which the blur (sigma 1 px, 2 pi sigma^2) spreads to a peak of about 2 r. Half the smallest
  // circle's is the floor: single noise votes make peaks of 1 / (2 pi) and stay below it.
  const float floor_votes = float(rmin);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      const float a = acc.at<float>(v, u);
      if (a >= floor_votes && a >= dil.at<float>(v, u)) peaks.push_back({u, v, a});
    }
  std::sort(peaks.begin(), peaks.end(), [](const Peak& a, const Peak& b) { return a.votes > b.votes; });
  if (peaks.size() > 3000) peaks.resize(3000);

  // Verification: outward edges at one distance from the peak, all around it.
  const int nbins = int(std::ceil((rmax + 2 - (rmin - 1)) / 0.5)) + 1;
  std::vector<DarkCircle> found;
  std::vector<float> votes;
  for (const Peak& pk : peaks) {
    const int reach = int(std::ceil(rmax + 2));
    std::vector<double> hist(size_t(nbins), 0.0);
    for (int v = std::max(0, pk.v - reach); v <= std::min(h - 1, pk.v + reach); ++v)
      for (int u = std::max(0, pk.u - reach); u <= std::min(w - 1, pk.u + reach); ++u) {
        const EdgePixel& e = edges[size_t(v) * w + u];
        if (e.mag <= 0) continue;
        const double du = u - pk.u, dv = v - pk.v, d = std::hypot(du, dv);
        if (d < rmin - 1 || d > rmax + 2 || (e.gx * du + e.gy * dv) < 0.85 * d) continue;
        hist[size_t((d - (rmin - 1)) / 0.5)] += e.mag;
      }
    int best = 0;
    double best_sum = 0;
    for (int b = 0; b + 2 < nbins; ++b) {
      const double s = hist[b] + hist[b + 1] + hist[b + 2];
      if (s > best_sum) best_sum = s, best = b;
    }
    if (!(best_sum > 0)) continue;
    const double r = (rmin - 1) + 0.5 * (best + 1.5);
    // A small circle has fewer edge pixels than 24 sectors: about one sector per pixel of its rim.
    const int sectors = std::clamp(int(std::lround(2 * std::numbers::pi * r)), 8, kSectors);
    bool sector[kSectors] = {};
    double sw = 0, sr = 0;
    for (int v = std::max(0, pk.v - reach); v <= std::min(h - 1, pk.v + reach); ++v)
      for (int u = std::max(0, pk.u - reach); u <= std::min(w - 1, pk.u + reach); ++u) {
        const EdgePixel& e = edges[size_t(v) * w + u];
        if (e.mag <= 0) continue;
        const double du = u - pk.u, dv = v - pk.v, d = std::hypot(du, dv);
        if (std::abs(d - r) > 1.5 || (e.gx * du + e.gy * dv) < 0.85 * d) continue;
        const double ang = std::atan2(dv, du) + std::numbers::pi;
        sector[std::min(sectors - 1, int(ang / (2 * std::numbers::pi) * sectors))] = true;
        sw += e.mag;
        sr += e.mag * d;
      }
    const double coverage = double(std::count(sector, sector + sectors, true)) / sectors;
    if (coverage < p.min_edge_coverage) continue;
    DarkCircle c;
    c.centre_px = Eigen::Vector2d(pk.u, pk.v);
    c.radius_px = sr / sw;
    c.edge_coverage = coverage;
    // The strongest peak of a circle comes first: a later peak inside a found circle is the same one.
    bool duplicate = false;
    for (const auto& f : found)
      if ((f.centre_px - c.centre_px).norm() < std::max(f.radius_px, c.radius_px)) duplicate = true;
    if (duplicate) continue;
    found.push_back(c);
  }

  for (auto& c : found) {
    const BlobCentroid b = dark_blob_centroid(image, c.centre_px, c.radius_px);
    c.centre_px = b.centre_px;
    c.elongation = b.elongation;
    // Two overlapping balls found as one blob are elongated (1.35 to 1.5 in the generated scenes);
    // one ball stays under 1.13 even with 150 photons per pixel. Its centroid is neither's centre.
    if (b.elongation > 1.3 || b.elongation == 0) c.crowded = true;
    const int u = int(std::lround(c.centre_px.x())), v = int(std::lround(c.centre_px.y()));
    const double rw = window_radius(c.radius_px);
    // Contrast against the ring just outside the window (mean), at the centre pixel.
    double bg = 0;
    int n = 0;
    for (int dv = -int(rw) - 3; dv <= int(rw) + 3; ++dv)
      for (int du = -int(rw) - 3; du <= int(rw) + 3; ++du) {
        const double d = std::hypot(du, dv);
        if (d <= rw || d > rw + 3 || u + du < 0 || v + dv < 0 || u + du >= w || v + dv >= h) continue;
        bg += image.at(u + du, v + dv);
        ++n;
      }
    c.contrast = n ? bg / n - image.at(std::clamp(u, 0, w - 1), std::clamp(v, 0, h - 1)) : 0;
  }
  for (size_t i = 0; i < found.size(); ++i)
    for (size_t j = 0; j < found.size(); ++j)
      if (i != j && (found[i].centre_px - found[j].centre_px).norm() <
                        window_radius(found[i].radius_px) + 3.0 + found[j].radius_px)
        found[i].crowded = true;
  return found;
}

}  // namespace fluoro
