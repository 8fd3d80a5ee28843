#include "pipelines/distal_locking/nail_detection.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "engine/image_mat.hpp"
#include "engine/median.hpp"

namespace fluoro {
namespace {

double bilinear(const cv::Mat& m, const Eigen::Vector2d& p) {
  const double u = std::clamp(p.x(), 0.0, double(m.cols - 1)), v = std::clamp(p.y(), 0.0, double(m.rows - 1));
  const int u0 = std::min(int(u), m.cols - 2), v0 = std::min(int(v), m.rows - 2);
  const double a = u - u0, b = v - v0;
  return (1 - a) * (1 - b) * m.at<float>(v0, u0) + a * (1 - b) * m.at<float>(v0, u0 + 1) +
         (1 - a) * b * m.at<float>(v0 + 1, u0) + a * b * m.at<float>(v0 + 1, u0 + 1);
}

bool inside(const cv::Mat& m, const Eigen::Vector2d& p, double margin) {
  return p.x() >= margin && p.y() >= margin && p.x() <= m.cols - 1 - margin && p.y() <= m.rows - 1 - margin;
}

// The part [s0, s1] of the line p + s d inside the image (margin m).
bool clip(const cv::Mat& img, const Eigen::Vector2d& p, const Eigen::Vector2d& d, double m, double* s0, double* s1) {
  double lo = -1e9, hi = 1e9;
  for (int k = 0; k < 2; ++k) {
    const double a = m, b = (k == 0 ? img.cols : img.rows) - 1 - m;
    if (std::abs(d[k]) < 1e-12) {
      if (p[k] < a || p[k] > b) return false;
      continue;
    }
    double t0 = (a - p[k]) / d[k], t1 = (b - p[k]) / d[k];
    if (t0 > t1) std::swap(t0, t1);
    lo = std::max(lo, t0), hi = std::min(hi, t1);
  }
  *s0 = lo, *s1 = hi;
  return hi > lo;
}

// The step across each edge of a candidate band: just outside minus just inside (medians along
// its length), the smaller of the two sides. Sampling near the edges, not at the band's middle,
// keeps a wider band around the nail (the bone's) from borrowing the nail's darkness.
double band_contrast(const cv::Mat& img, const Eigen::Vector2d& p, const Eigen::Vector2d& d, const Eigen::Vector2d& n,
                     double w) {
  double s0, s1;
  if (!clip(img, p, d, 2, &s0, &s1)) return 0;
  std::vector<double> a, b;
  const double delta = 2.0 + 0.12 * w;
  const double out = 0.5 * w + delta, in = std::max(0.0, 0.5 * w - delta);
  for (double s = s0; s <= s1; s += 2.0) {
    const Eigen::Vector2d c = p + s * d;
    const Eigen::Vector2d pa = c + out * n, pb = c - out * n;
    if (!inside(img, pa, 1) || !inside(img, pb, 1)) continue;
    a.push_back(bilinear(img, pa) - bilinear(img, c + in * n));
    b.push_back(bilinear(img, pb) - bilinear(img, c - in * n));
  }
  if (a.size() < 10) return 0;
  return std::min(upper_median(a), upper_median(b));
}

// Sub-pixel edges from the band's mean cross profile (the Hough lines are quantised and Canny's
// edges sit where the smoothed step is steepest): a metal cylinder's chord falls to zero with an
// infinite slope at its silhouette, so the steepest descent of the mean profile on either side,
// interpolated by a parabola, is the silhouette.
void refine_band_edges(const cv::Mat& img, NailBand& b, const Eigen::Vector2d& n) {
  double s0, s1;
  const double w = b.width_px;
  if (!clip(img, b.axis_point, b.direction, 0.8 * w + 4, &s0, &s1)) return;
  const int half = int(std::ceil(0.8 * w)) + 3;
  std::vector<std::vector<double>> cols(size_t(4 * half + 1));
  for (double s = s0; s <= s1; s += 1.0)
    for (int k = -2 * half; k <= 2 * half; ++k)
      cols[size_t(k + 2 * half)].push_back(bilinear(img, b.axis_point + s * b.direction + 0.5 * k * n));
  std::vector<double> prof;  // medians: holes and spheres are a minority of the band's length
  for (auto& c : cols) prof.push_back(upper_median(c));
  const auto steepest = [&](int from, int to, int sign) {
    int arg = -1;
    double best = 0;
    for (int k = std::max(from, 1); k < std::min(to, int(prof.size()) - 1); ++k) {
      const double g = sign * (prof[size_t(k + 1)] - prof[size_t(k - 1)]);
      if (g > best) best = g, arg = k;
    }
    if (arg < 2 || arg > int(prof.size()) - 3) return double(arg);
    const double gm = sign * (prof[size_t(arg)] - prof[size_t(arg - 2)]), g0 = best,
                 gp = sign * (prof[size_t(arg + 2)] - prof[size_t(arg)]);
    const double den = gm - 2 * g0 + gp;
    return arg + (std::abs(den) > 1e-12 ? 0.5 * (gm - gp) / den : 0.0);
  };
  const int mid = 2 * half;
  // Going outwards the profile rises (dark metal to bright) on the + side and falls towards it on the - side.
  const double plus = steepest(mid, int(prof.size()), +1), minus = steepest(0, mid + 1, -1);
  if (plus < 0 || minus < 0) return;
  const double tp = 0.5 * (plus - mid), tm = 0.5 * (minus - mid);
  const double width = tp - tm;
  if (!(width > 0.5 * w && width < 1.5 * w)) return;
  b.axis_point += 0.5 * (tp + tm) * n;
  b.width_px = width;
}

}  // namespace

NailDetection detect_nail(const Image& xray, const NailModel& nail, double min_w, double max_w,
                          const std::vector<DarkCircle>& occluders) {
  NailDetection out;
  cv::Mat img = mat_view(xray);
  cv::Mat smooth;
  cv::GaussianBlur(img, smooth, cv::Size(0, 0), 1.0);
  double lo, hi;
  cv::minMaxLoc(smooth, &lo, &hi);
  cv::Mat u8, edges;
  smooth.convertTo(u8, CV_8U, 255.0 / std::max(1e-9, hi - lo), -lo * 255.0 / std::max(1e-9, hi - lo));
  cv::Canny(u8, edges, 20, 60);
  std::vector<cv::Vec3f> lines;
  const int size = std::min(xray.width, xray.height);
  cv::HoughLines(edges, lines, 1, std::numbers::pi / 360, std::max(20, size / 10));
  if (lines.size() > 80) lines.resize(80);

  // Pairs of near-parallel lines at the nail's width with the darker band between them.
  double best = 0;
  for (size_t i = 0; i < lines.size(); ++i)
    for (size_t j = i + 1; j < lines.size(); ++j) {
      double ri = lines[i][0], ti = lines[i][1], rj = lines[j][0], tj = lines[j][1];
      if (std::abs(ti - tj) > std::numbers::pi / 2) tj += (tj < ti ? std::numbers::pi : -std::numbers::pi), rj = -rj;  // same normal
      if (std::abs(ti - tj) > 1.5 * std::numbers::pi / 180) continue;
      const double w = std::abs(ri - rj);
      if (w < min_w || w > max_w) continue;
      const double t = 0.5 * (ti + tj);
      const Eigen::Vector2d n(std::cos(t), std::sin(t)), d(-n.y(), n.x());
      const Eigen::Vector2d p = 0.5 * (ri + rj) * n;
      const double c = band_contrast(smooth, p, d, n, w);
      if (c > best) {
        best = c;
        NailBand b;
        b.edge_a = {Eigen::Vector2d(std::cos(ti), std::sin(ti)), ri};
        b.edge_b = {Eigen::Vector2d(std::cos(tj), std::sin(tj)), rj};
        b.axis_point = p;
        b.direction = d.x() < 0 || (d.x() == 0 && d.y() < 0) ? Eigen::Vector2d(-d) : d;
        b.width_px = w;
        b.contrast = c;
        out.band = b;
      }
    }
  if (!(best > 0)) {
    out.failure_reason = "no nail: no pair of parallel edges at the nail's width with a darker band between them";
    return out;
  }
  NailBand& b = out.band;
  const Eigen::Vector2d n(-b.direction.y(), b.direction.x());
  refine_band_edges(smooth, b, n);
  const double w = b.width_px;

  // The profile along the medial axis: the band's centre strip, and whether the nail is there
  // (its flanks dark against the outside; past the nail's tip they are not).
  double s0, s1;
  clip(smooth, b.axis_point, b.direction, 0.5 * w + 4, &s0, &s1);
  std::vector<double> centre, flank, pos;
  for (double s = s0; s <= s1; s += 1.0) {
    const Eigen::Vector2d c = b.axis_point + s * b.direction;
    double sum = 0;
    for (int k = -2; k <= 2; ++k) sum += bilinear(smooth, c + 0.1 * w * k * n);
    centre.push_back(sum / 5);
    flank.push_back(0.5 * (bilinear(smooth, c + 0.4 * w * n) + bilinear(smooth, c - 0.4 * w * n)));
    pos.push_back(s);
  }
  // The nail is where its flanks (beside any hole) are as dark as along most of the band; past
  // its tip they are brighter by about the band's contrast.
  const double flank_level = upper_median(flank);
  std::vector<bool> present(centre.size());
  std::vector<double> metal;
  for (size_t k = 0; k < centre.size(); ++k) {
    present[k] = flank[k] < flank_level + 0.3 * b.contrast;
    if (present[k]) metal.push_back(centre[k]);
  }
  const double metal_level = upper_median(metal);
  // Candidate holes: bright windows along the medial axis, one nail width apart at least.
  std::vector<int> candidates;
  std::vector<bool> taken(centre.size(), false);
  for (int h = 0; h < 8; ++h) {
    int arg = -1;
    for (size_t k = 0; k < centre.size(); ++k)
      if (!taken[k] && present[k] && (arg < 0 || centre[k] > centre[size_t(arg)])) arg = int(k);
    // A hole half hidden by a sphere is still brighter than the rod by a tenth of the band's contrast.
    if (arg < 0 || centre[size_t(arg)] - metal_level < 0.1 * b.contrast) break;
    candidates.push_back(arg);
    for (size_t k = 0; k < centre.size(); ++k)
      if (std::abs(pos[k] - pos[size_t(arg)]) < 1.2 * w) taken[k] = true;
  }
  // The holes: the brightest set of candidates spaced as NAIL.json's holes at the band's scale
  // (the spacing shortens with the tilt along the nail, by up to a fifth at 35 degrees).
  std::vector<double> model_x;
  for (const auto& h : nail.holes) model_x.push_back(h.center_mm.x() / nail.diameter_mm * w);
  std::sort(model_x.begin(), model_x.end());
  const int wanted = int(model_x.size());
  std::vector<int> peaks;
  double best_score = -HUGE_VAL;
  if (wanted == 1 && !candidates.empty()) peaks = {candidates[0]};
  for (size_t i = 0; wanted >= 2 && i < candidates.size(); ++i)
    for (size_t j = 0; j < candidates.size(); ++j) {
      if (i == j) continue;
      // Candidates i and j as the first and last holes, in either direction along the band.
      const double span = pos[size_t(candidates[j])] - pos[size_t(candidates[i])];
      const double scale = span / (model_x.back() - model_x.front());
      // The band's width is read up to 10 % narrow (the blur pulls its edges in): up to 1.25.
      if (!(std::abs(scale) > 0.8 && std::abs(scale) < 1.25)) continue;
      std::vector<int> set;
      double score = 0;
      for (double x : model_x) {
        const double at = pos[size_t(candidates[i])] + (x - model_x.front()) * scale;
        int found = -1;
        for (int c : candidates)
          if (std::abs(pos[size_t(c)] - at) < 0.35 * w) found = c;
        if (found < 0) break;
        set.push_back(found);
        score += centre[size_t(found)] - metal_level;
      }
      if (int(set.size()) == wanted && score > best_score) best_score = score, peaks = set;
    }
  if (int(peaks.size()) < wanted) {
    out.failure_reason = "holes not separable: " + std::to_string(candidates.size()) +
                         " bright windows along the nail, no " + std::to_string(wanted) + " of them spaced as the nail's holes";
    return out;
  }
  std::sort(peaks.begin(), peaks.end());

  for (int k : peaks) {
    const Eigen::Vector2d c = b.axis_point + pos[size_t(k)] * b.direction;
    const int half = int(std::ceil(0.7 * w));
    const int u0 = std::max(0, int(c.x()) - half), v0 = std::max(0, int(c.y()) - half);
    const int u1 = std::min(xray.width - 1, int(c.x()) + half), v1 = std::min(xray.height - 1, int(c.y()) + half);
    // The lens on the image as it is (the band's smoothing would round it off).
    const cv::Mat roi = img(cv::Rect(u0, v0, u1 - u0 + 1, v1 - v0 + 1));
    double rlo, rhi;
    cv::Point at;
    cv::minMaxLoc(roi, &rlo, &rhi, nullptr, &at);
    // Two outlines: at half the way from the rod's level to the hole's brightest, the hole's edge
    // (in a fronto-parallel view its diameter gives the depth); at 75 % the lens, where the ray
    // crosses little metal. As the view tilts the half-way outline stays near the hole's mid-plane
    // circle (the partial-chord border is symmetric about it) while the lens shrinks: the lens is
    // what the technician is to make round.
    const auto outline_ellipse = [&](double fraction, cv::RotatedRect* e) {
      const double level = metal_level + fraction * (rhi - metal_level);
      cv::Mat mask = roi > level;
      cv::Mat labels;
      cv::connectedComponents(mask, labels, 8, CV_32S);
      const int label = labels.at<int>(at);
      // Sub-pixel outline: where the image crosses the level between each pixel of the blob and
      // each of its 4-neighbours outside it (linear interpolation), not the boundary pixels'
      // centres, which sit up to a pixel inside and would shrink a 12 px hole by 8 %.
      std::vector<cv::Point2f> pts;
      for (int v = 0; v < roi.rows; ++v)
        for (int u = 0; u < roi.cols; ++u) {
          if (labels.at<int>(v, u) != label) continue;
          const int du[4] = {1, -1, 0, 0}, dv[4] = {0, 0, 1, -1};
          for (int k = 0; k < 4; ++k) {
            const int uu = u + du[k], vv = v + dv[k];
            if (uu < 0 || vv < 0 || uu >= roi.cols || vv >= roi.rows || labels.at<int>(vv, uu) == label) continue;
            const double a = roi.at<float>(v, u), b = roi.at<float>(vv, uu);
            const double t = a > b ? std::clamp((a - level) / (a - b), 0.0, 1.0) : 0.5;
            const Eigen::Vector2d q(u0 + u + t * du[k], v0 + v + t * dv[k]);
            // Outline points next to a known occluder (a guide sphere over the rim) are left out.
            bool hidden = false;
            for (const auto& o : occluders) hidden = hidden || (q - o.centre_px).norm() < o.radius_px + 1.5;
            if (!hidden) pts.emplace_back(float(q.x()), float(q.y()));
          }
        }
      if (pts.size() < 6) return false;
      *e = cv::fitEllipse(pts);
      return true;
    };
    cv::RotatedRect e, lens;
    if (!outline_ellipse(0.5, &e) || !outline_ellipse(0.75, &lens)) {
      out.failure_reason = "holes not separable: a hole's outline has too few points";
      return out;
    }
    HoleEllipse h;
    h.centre_px = Eigen::Vector2d(e.center.x, e.center.y);
    h.major_px = std::max(e.size.width, e.size.height);
    h.minor_px = std::min(e.size.width, e.size.height);
    h.angle_deg = e.size.width >= e.size.height ? e.angle : e.angle + 90.0;
    h.lens_major_px = std::max(lens.size.width, lens.size.height);
    h.lens_minor_px = std::min(lens.size.width, lens.size.height);
    out.holes.push_back(h);
  }
  out.ok = true;
  return out;
}

}  // namespace fluoro
