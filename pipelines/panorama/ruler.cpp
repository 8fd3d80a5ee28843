#include "pipelines/panorama/ruler.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "engine/ellipse_erosion.hpp"
#include "engine/median.hpp"

namespace fluoro {

Eigen::Vector2d RulerThread::direction() const { return {std::cos(angle_rad), std::sin(angle_rad)}; }
Eigen::Vector2d RulerThread::normal() const { return {-std::sin(angle_rad), std::cos(angle_rad)}; }

RulerStrip ruler_strip(const cv::Mat& image, const cv::Mat& fov_mask, const RulerThread& t, int half_length,
                       int b_first, int b_last) {
  const Eigen::Vector2d e = t.direction(), n = t.normal();
  const Eigen::Vector2d origin = t.centre + (t.offset_px + b_first) * n - half_length * e;
  // Destination (x, y) -> source origin + x e + y n.
  cv::Mat m = (cv::Mat_<double>(2, 3) << e.x(), n.x(), origin.x(), e.y(), n.y(), origin.y());
  RulerStrip s;
  s.half_length = half_length;
  s.b_first = b_first;
  const cv::Size size(2 * half_length + 1, b_last - b_first + 1);
  cv::warpAffine(image, s.image, m, size, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::warpAffine(fov_mask, s.valid, m, size, cv::INTER_NEAREST | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, cv::Scalar(0));
  return s;
}

namespace {

// True when every row of strip column x in [y0, y1] is inside the field of view.
bool column_valid(const RulerStrip& s, int x, int y0, int y1) {
  for (int y = std::max(0, y0); y <= std::min(s.valid.rows - 1, y1); ++y)
    if (!s.valid.at<uint8_t>(y, x)) return false;
  return y0 >= 0 && y1 < s.valid.rows;
}

// Moves the thread onto the centroid of its dark band, column by column, with a robust line fit
// (columns hidden by an object or crossed by a wire fall out as outliers). False when the band is
// not darker than its sides over enough columns.
bool refine_thread(const cv::Mat& image, const cv::Mat& mask, RulerThread& t, int half_length, int iterations,
                   const std::vector<double>& skip_a = {}, double skip_half = 0) {
  const double initial_width = t.width_px;
  for (int iter = 0; iter < iterations; ++iter) {
    const int h = int(std::lround(0.5 * t.width_px)) + 3;
    const RulerStrip s = ruler_strip(image, mask, t, half_length, -h, h);
    std::vector<cv::Point2f> pts;
    std::vector<double> contrasts, sides;
    const size_t span = size_t(2 * h + 1);
    std::vector<double> profiles;  // span values per used column, flat (one allocation, not one per column)
    profiles.reserve(size_t(s.image.cols) * span);
    int used = 0;
    for (int x = 0; x < s.image.cols; ++x) {
      if (!column_valid(s, x, 0, 2 * h)) continue;
      // Columns of a graduation darken one side of the band and would pull its centroid over.
      const double ax = x - half_length;
      if (std::any_of(skip_a.begin(), skip_a.end(), [&](double a) { return std::abs(a - ax) <= skip_half; })) continue;
      auto v = [&](int y) { return double(s.image.at<float>(y, x)); };
      const double left = 0.5 * (v(0) + v(1)), right = 0.5 * (v(2 * h) + v(2 * h - 1));
      const double bg = std::max(left, right);
      double sw = 0, swb = 0, lo = bg;
      for (int y = 2; y <= 2 * h - 2; ++y) {
        const double w = std::max(0.0, bg - v(y));
        sw += w, swb += w * y, lo = std::min(lo, v(y));
      }
      if (sw <= 0) continue;
      sides.push_back(left - right);
      contrasts.push_back(bg - lo);
      pts.emplace_back(float(x - half_length), float(swb / sw + s.b_first));
      for (int y = 0; y <= 2 * h; ++y) profiles.push_back(bg - v(y));
      ++used;
    }
    if (used < 20) return false;
    // Keep the columns where the band is clearly there (not hidden by metal, not saturated).
    // The band's typical depth among the columns where it shows at all: a clamp's shadow can
    // cover more than half of them, and its flat, saturated columns would set the scale.
    std::vector<double> sorted = contrasts;
    std::sort(sorted.begin(), sorted.end());
    const double high = sorted[sorted.size() * 9 / 10];
    std::vector<double> shown, shown_sides;
    for (size_t i = 0; i < contrasts.size(); ++i)
      if (contrasts[i] > 0.3 * high) shown.push_back(contrasts[i]), shown_sides.push_back(sides[i]);
    if (shown.size() < 20) return false;
    const double typical = upper_median(shown);
    if (!(typical > 0)) return false;
    std::vector<cv::Point2f> good;
    std::vector<size_t> good_columns;
    const double typical_side = upper_median(shown_sides);
    for (size_t i = 0; i < pts.size(); ++i)
      if (contrasts[i] > 0.5 * typical && contrasts[i] < 1.6 * typical && std::abs(sides[i] - typical_side) < 0.3 * typical) {
        good.push_back(pts[i]);
        good_columns.push_back(i);
      }
    if (good.size() < 20) return false;
    cv::Vec4f line;
    for (int trim = 0; trim < 3; ++trim) {  // robust fit, then drop the points far off it and refit
      cv::fitLine(good, line, cv::DIST_HUBER, 0, 0.01, 0.01);
      std::vector<double> res;
      for (const auto& q : good) res.push_back(std::abs((q.y - line[3]) * line[0] - (q.x - line[2]) * line[1]));
      const double cut = std::max(0.15, 3 * 1.4826 * upper_median(res));
      std::vector<cv::Point2f> kept;
      for (size_t i = 0; i < good.size(); ++i)
        if (res[i] <= cut) kept.push_back(good[i]);
      if (kept.size() < 20 || kept.size() == good.size()) break;
      good = kept;
    }
    const double vx = line[0], vy = line[1], x0 = line[2], y0 = line[3];
    const double b0 = y0 - x0 * vy / vx;
    const Eigen::Vector2d e = t.direction(), n = t.normal();
    const Eigen::Vector2d e2 = (vx * e + vy * n).normalized();
    RulerThread r = t;
    r.angle_rad = std::atan2(e2.y(), e2.x());
    r.offset_px = (t.offset_px + b0) * r.normal().dot(n);
    // Width: the band's full width at half its depth in the mean profile.
    // The band's width from the median profile: graduation columns (a fifth of them, dark on one
    // side) would widen a mean one.
    std::vector<double> profile, row(good_columns.size());
    for (size_t y = 0; y < span; ++y) {
      for (size_t k = 0; k < good_columns.size(); ++k) row[k] = profiles[good_columns[k] * span + y];
      profile.push_back(upper_median(row));
    }
    const double peak = *std::max_element(profile.begin(), profile.end());
    int wide = 0;
    for (double p : profile) wide += p > 0.5 * peak;
    r.width_px = std::clamp(double(wide), std::max(2.0, 0.6 * initial_width), std::max(3.0 * initial_width, 3.0));
    const bool converged = std::abs(b0) < 0.01 && std::abs(vy / vx) < 1e-5;
    t = r;
    if (converged) break;
  }
  return true;
}

struct Lattice {
  std::vector<double> a;
  std::vector<long> k;
  double pitch = 0, phase = 0, rms = 0;
};

// Fits a = phase + k pitch to mark centres, with the integer k and the outliers (a wire's shadow,
// a missed mark) decided by the best-supported reference mark.
Lattice fit_lattice(const std::vector<double>& centres) {
  Lattice best;
  if (centres.size() < 4) return best;
  std::vector<double> gaps;
  for (size_t i = 1; i < centres.size(); ++i) gaps.push_back(centres[i] - centres[i - 1]);
  double pitch = upper_median(gaps);
  if (!(pitch > 3)) return best;
  size_t best_support = 0;
  double ref = centres[0];
  for (double c : centres) {
    size_t support = 0;
    for (double d : centres) {
      const double q = (d - c) / pitch;
      support += std::abs(q - std::round(q)) < 0.15;
    }
    if (support > best_support) best_support = support, ref = c;
  }
  double phase = ref;
  for (int iter = 0; iter < 4; ++iter) {
    Lattice l;
    Eigen::MatrixXd A;
    std::vector<double> as;
    std::vector<long> ks;
    for (double d : centres) {
      const double q = (d - phase) / pitch;
      if (std::abs(q - std::round(q)) < (iter < 2 ? 0.2 : 0.12)) as.push_back(d), ks.push_back(std::lround(q));
    }
    if (as.size() < 4) return best;
    A.resize(long(as.size()), 2);
    Eigen::VectorXd y(long(as.size()));
    for (size_t i = 0; i < as.size(); ++i) A(long(i), 0) = 1, A(long(i), 1) = double(ks[i]), y(long(i)) = as[i];
    const Eigen::Vector2d sol = A.colPivHouseholderQr().solve(y);
    phase = sol(0), pitch = sol(1);
    l.a = as, l.k = ks, l.phase = phase, l.pitch = pitch;
    l.rms = std::sqrt((A * sol - y).squaredNorm() / double(as.size()));
    best = l;
  }
  return best;
}

// Graduation centres on one side of the thread: the strip's rows beside the thread summed into a
// 1D signal along the ruler, whose falling and rising edges pair up into marks.
std::vector<double> find_marks(const RulerStrip& s, int y0, int y1, double max_width) {
  const int nx = s.image.cols;
  std::vector<double> p(size_t(nx), std::nan(""));
  for (int x = 0; x < nx; ++x) {
    if (!column_valid(s, x, y0, y1)) continue;
    double sum = 0;
    for (int y = y0; y <= y1; ++y) sum += s.image.at<float>(y, x);
    p[size_t(x)] = sum / (y1 - y0 + 1);
  }
  std::vector<double> d(size_t(nx), std::nan(""));
  std::vector<double> mags;
  for (int x = 1; x + 1 < nx; ++x) {
    d[size_t(x)] = 0.5 * (p[size_t(x + 1)] - p[size_t(x - 1)]);
    if (std::isfinite(d[size_t(x)])) mags.push_back(std::abs(d[size_t(x)]));
  }
  if (mags.size() < 10) return {};
  // Noise of the derivative from its lower quartile: graduations (and a wire) fill a good part of
  // the columns, so the median would count them as noise.
  std::nth_element(mags.begin(), mags.begin() + long(mags.size() / 4), mags.end());
  const double sigma = mags[mags.size() / 4] / 0.3186 + 1e-6;
  struct Edge { double x; int sign; double mag; };
  std::vector<Edge> edges;
  for (int x = 2; x + 2 < nx; ++x) {
    const double a = d[size_t(x - 1)], b = d[size_t(x)], c = d[size_t(x + 1)];
    if (!std::isfinite(a) || !std::isfinite(b) || !std::isfinite(c)) continue;
    const bool is_min = b < a && b <= c && b < -6 * sigma, is_max = b > a && b >= c && b > 6 * sigma;
    if (!is_min && !is_max) continue;
    const double den = a - 2 * b + c;
    const double off = std::abs(den) > 1e-12 ? 0.5 * (a - c) / den : 0.0;
    edges.push_back({x + std::clamp(off, -0.5, 0.5), is_min ? -1 : 1, std::abs(b)});
  }
  std::vector<double> centres;
  for (size_t i = 0; i + 1 < edges.size(); ++i) {
    const Edge& f = edges[i];
    const Edge& r = edges[i + 1];
    if (f.sign != -1 || r.sign != 1) continue;
    if (r.x - f.x > max_width || r.x - f.x < 1) continue;
    if (f.mag > 3 * r.mag || r.mag > 3 * f.mag) continue;  // a step (object edge), not a mark
    centres.push_back(0.5 * (f.x + r.x) - s.half_length);
  }
  return centres;
}

struct SideMarks {
  Lattice lattice;
  int found = 0;
};

SideMarks marks_on_side(const cv::Mat& image, const cv::Mat& mask, const RulerThread& t, int half_length, int side) {
  const double w = t.width_px;
  const int near = int(std::ceil(0.5 * w + 1)), far = near + int(std::ceil(1.2 * w));
  const RulerStrip s = ruler_strip(image, mask, t, half_length, side > 0 ? near : -far, side > 0 ? far : -near);
  const std::vector<double> c = find_marks(s, 0, s.image.rows - 1, std::max(4.0, 2.5 * w));
  SideMarks m;
  m.found = int(c.size());
  m.lattice = fit_lattice(c);
  return m;
}

// Mark lengths from the strip: how far from the thread each mark stays dark; the longer of the two
// alternating groups are the 10 mm marks, and those clearly longer still the 50 mm marks.
void classify_marks(RulerFrame& r) {
  const RulerStrip& s = r.strip;
  const int start = int(std::ceil(0.5 * r.thread.width_px)) + 3 - s.b_first;
  if (start >= s.image.rows - 2 || r.mark_a.size() < 4) return;
  std::vector<double> length(r.mark_a.size(), -1);
  std::vector<bool> censored(r.mark_a.size(), false);
  for (size_t m = 0; m < r.mark_a.size(); ++m) {
    const int x = int(std::lround(r.mark_a[m])) + s.half_length;
    const int xb = int(std::lround(r.mark_a[m] + 0.5 * r.pitch_px)) + s.half_length;  // between marks
    if (x < 1 || xb < 1 || x + 1 >= s.image.cols || xb + 1 >= s.image.cols) continue;
    // Rows outside the field of view end the scan; a mark still dark there is at least that long.
    std::vector<double> dark;
    for (int y = start; y < s.image.rows; ++y) {
      if (!s.valid.at<uint8_t>(y, x - 1) || !s.valid.at<uint8_t>(y, x + 1) || !s.valid.at<uint8_t>(y, xb)) break;
      const double on = (s.image.at<float>(y, x - 1) + s.image.at<float>(y, x) + s.image.at<float>(y, x + 1)) / 3;
      dark.push_back(s.image.at<float>(y, xb) - on);
    }
    if (dark.size() < 4) continue;
    // The mark's depth near the thread (the first rows still hold the blurred thread edge), then
    // its extent: the rows where it stays darker than half of that.
    const size_t near = std::min(dark.size(), size_t(std::ceil(r.thread.width_px)) + 2);
    const double ref = *std::max_element(dark.begin(), dark.begin() + long(near));
    if (ref <= 0) continue;
    size_t first = 0;
    while (first < dark.size() && dark[first] <= 0.5 * ref) ++first;
    size_t last = first;
    while (last < dark.size() && dark[last] > 0.5 * ref) ++last;
    const int len = int(last);
    censored[m] = last == dark.size();
    length[m] = len;
  }
  std::vector<double> even, odd;
  for (size_t m = 0; m < length.size(); ++m)
    if (length[m] > 0 && !censored[m]) (r.mark_k[m] % 2 == 0 ? even : odd).push_back(length[m]);
  if (even.size() < 2 || odd.size() < 2) return;
  const double me = upper_median(even), mo = upper_median(odd);
  if (std::abs(me - mo) < 2) return;
  r.medium_parity = me > mo ? 0 : 1;
  const double medium = std::max(me, mo);
  std::vector<int> residues;
  for (size_t m = 0; m < length.size(); ++m)
    if (length[m] > 1.25 * medium + 1 && ((r.mark_k[m] % 2) + 2) % 2 == r.medium_parity)
      residues.push_back(int(((r.mark_k[m] % 10) + 10) % 10));
  // Negative evidence: a mark of the 10 mm class seen whole (not cut by the field's edge) and as
  // long as the 10 mm marks is not a 50 mm mark, so its index modulo 10 is not the 50 mm marks'.
  // Marks read shorter (a wire across them) or longer say nothing here. An occluder's edge can cut
  // a 50 mm mark to just the 10 mm length, so a residue is ruled out only by two such marks (50 mm
  // apart, which one clamp or wire does not both cut). When the field's edge cuts the one 50 mm
  // mark a frame shows, the others can then rule out every residue but its own.
  int short_reads[10] = {};
  for (size_t m = 0; m < length.size(); ++m)
    if (length[m] > 0 && !censored[m] && std::abs(length[m] - medium) <= 0.15 * medium)
      ++short_reads[((r.mark_k[m] % 10) + 10) % 10];
  bool excluded[10] = {};
  for (int q = 0; q < 10; ++q) excluded[q] = short_reads[q] >= 2;
  std::vector<int> possible;
  for (int q = r.medium_parity; q < 10; q += 2)
    if (!excluded[q]) possible.push_back(q);
  // A long reading at a residue ruled out (a wire or the clamp along a 10 mm mark) is dropped.
  residues.erase(std::remove_if(residues.begin(), residues.end(), [&](int v) { return excluded[v]; }), residues.end());
  if (!residues.empty()) {
    if (std::all_of(residues.begin(), residues.end(), [&](int v) { return v == residues[0]; })) r.long_residue = residues[0];
  } else if (possible.size() == 1) {
    r.long_residue = possible[0];
  }
}

}  // namespace

std::optional<RulerFrame> find_ruler(const cv::Mat& image, const cv::Mat& fov_mask) {
  const int W = image.cols, H = image.rows;
  const Eigen::Vector2d centre(0.5 * (W - 1), 0.5 * (H - 1));
  const int half_length = int(std::ceil(0.5 * std::hypot(W, H)));
  double lo = 0, hi = 0;
  cv::minMaxLoc(image, &lo, &hi, nullptr, nullptr, fov_mask);
  if (!(hi > lo)) return std::nullopt;
  cv::Mat img8;
  image.convertTo(img8, CV_8U, 255.0 / (hi - lo), -lo * 255.0 / (hi - lo));
  cv::GaussianBlur(img8, img8, cv::Size(0, 0), 1.0);
  // Canny thresholds from the image's own gradients: a ruler's edges are among its strongest.
  cv::Mat gx, gy, mag;
  cv::Sobel(img8, gx, CV_32F, 1, 0);
  cv::Sobel(img8, gy, CV_32F, 0, 1);
  cv::magnitude(gx, gy, mag);
  const cv::Mat inner = erode_ellipse(fov_mask, 13);
  std::vector<double> mags;
  for (int v = 0; v < H; v += 2)
    for (int u = 0; u < W; u += 2)
      if (inner.at<uint8_t>(v, u)) mags.push_back(mag.at<float>(v, u));
  if (mags.size() < 100) return std::nullopt;
  std::nth_element(mags.begin(), mags.begin() + long(mags.size() * 92 / 100), mags.end());
  const double high = std::max(20.0, mags[mags.size() * 92 / 100]);
  cv::Mat edges;
  cv::Canny(img8, edges, 0.4 * high, high, 3, true);
  edges &= inner;
  std::vector<cv::Vec3f> lines;
  cv::HoughLines(edges, lines, 1, std::numbers::pi / 360, std::max(30, std::min(W, H) / 8));
  if (lines.size() > 80) lines.resize(80);
  // Pairs of parallel lines a thread's width apart (the seed's constraint on the Hough votes).
  struct Candidate { RulerThread t; double votes; };
  std::vector<Candidate> candidates;
  const double max_sep = std::max(12.0, std::min(W, H) / 15.0);
  for (size_t i = 0; i < lines.size(); ++i)
    for (size_t j = i + 1; j < lines.size(); ++j) {
      double r1 = lines[i][0], t1 = lines[i][1], r2 = lines[j][0], t2 = lines[j][1];
      if (t2 - t1 > std::numbers::pi / 2) t2 -= std::numbers::pi, r2 = -r2;
      if (t1 - t2 > std::numbers::pi / 2) t2 += std::numbers::pi, r2 = -r2;
      if (std::abs(t1 - t2) > 1.5 * std::numbers::pi / 180) continue;
      const double sep = std::abs(r1 - r2);
      if (sep < 2.5 || sep > max_sep) continue;
      const double th = 0.5 * (t1 + t2), rho = 0.5 * (r1 + r2);
      RulerThread t;
      t.centre = centre;
      t.angle_rad = th + std::numbers::pi / 2;
      t.offset_px = std::cos(th) * centre.x() + std::sin(th) * centre.y() - rho;
      t.width_px = sep;
      bool dup = false;
      for (auto& c : candidates)
        if (std::abs(std::remainder(c.t.angle_rad - t.angle_rad, 2 * std::numbers::pi)) < 0.02 &&
            std::abs(c.t.offset_px - t.offset_px) < 3)
          dup = true;
      if (!dup) candidates.push_back({t, std::min(lines[i][2], lines[j][2])});
      if (candidates.size() >= 8) break;
    }
  // Screened candidates; the ruler is among those with nearly the most graduations (a line through
  // the graduations themselves can collect as many) the one with the strongest Hough lines.
  struct Screened { RulerFrame frame; double votes; };
  std::vector<Screened> screened;
  for (auto& c : candidates) {
    RulerThread t = c.t;
    // Screening: a few steps are enough to tell the ruler from a bone edge or a wire.
    if (!refine_thread(image, fov_mask, t, half_length, 3)) continue;
    const SideMarks plus = marks_on_side(image, fov_mask, t, half_length, +1);
    const SideMarks minus = marks_on_side(image, fov_mask, t, half_length, -1);
    const bool flip = minus.lattice.a.size() > plus.lattice.a.size();
    const SideMarks& m = flip ? minus : plus;
    if (m.lattice.a.size() < 4) continue;
    RulerFrame r;
    r.thread = t;
    Lattice lat = m.lattice;
    if (flip) {  // graduations on the +normal side: turn the direction round, a changes sign
      r.thread.angle_rad = std::remainder(t.angle_rad + std::numbers::pi, 2 * std::numbers::pi);
      r.thread.offset_px = -t.offset_px;
      std::vector<double> a(lat.a.rbegin(), lat.a.rend());
      for (double& x : a) x = -x;
      lat = fit_lattice(a);
      if (lat.a.size() < 4) continue;
    }
    r.mark_a = lat.a;
    r.mark_k = lat.k;
    r.pitch_px = lat.pitch;
    r.phase_px = lat.phase;
    r.lattice_rms_px = lat.rms;
    r.marks_found = m.found;
    screened.push_back({r, c.votes});
  }
  size_t most = 0;
  for (const auto& c : screened) most = std::max(most, c.frame.mark_a.size());
  std::optional<RulerFrame> best;
  double best_votes = -1;
  for (const auto& c : screened)
    if (double(c.frame.mark_a.size()) >= 0.8 * double(most) && c.votes > best_votes) best_votes = c.votes, best = c.frame;
  if (best) {
    // Once the graduations are known, the thread again without their columns (unbiased centre),
    // and the graduations again along the final thread.
    RulerThread t = best->thread;
    if (refine_thread(image, fov_mask, t, half_length, 10, best->mark_a, 0.5 * best->pitch_px * 0.4 + 2)) {
      const SideMarks m = marks_on_side(image, fov_mask, t, half_length, +1);
      if (m.lattice.a.size() >= 4) {
        best->thread = t;
        best->mark_a = m.lattice.a;
        best->mark_k = m.lattice.k;
        best->pitch_px = m.lattice.pitch;
        best->phase_px = m.lattice.phase;
        best->lattice_rms_px = m.lattice.rms;
        best->marks_found = m.found;
      }
    }
    const double w = best->thread.width_px;
    best->strip = ruler_strip(image, fov_mask, best->thread, half_length, -int(std::ceil(w)), int(std::ceil(0.5 * w + 8 * w)));
    classify_marks(*best);
  }
  return best;
}

}  // namespace fluoro
