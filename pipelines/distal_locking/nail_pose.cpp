#include "pipelines/distal_locking/nail_pose.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <unsupported/Eigen/LevenbergMarquardt>
#include <unsupported/Eigen/NumericalDiff>

#include "engine/nail_chord.hpp"
#include <opencv2/imgproc.hpp>
#include <tbb/parallel_for.h>

namespace fluoro {
namespace {

Eigen::Matrix3d rotation(const Eigen::Vector3d& w) {
  const double a = w.norm();
  return a < 1e-300 ? Eigen::Matrix3d::Identity() : Eigen::AngleAxisd(a, w / a).toRotationMatrix();
}

// A rotation with the given x and (approximately) z axes: z is made orthogonal to x.
Eigen::Matrix3d frame_from_x_z(const Eigen::Vector3d& x, const Eigen::Vector3d& z_hint) {
  const Eigen::Vector3d X = x.normalized();
  Eigen::Vector3d Z = z_hint - z_hint.dot(X) * X;
  if (Z.norm() < 1e-9) Z = X.unitOrthogonal();
  Z.normalize();
  Eigen::Matrix3d R;
  R << X, Z.cross(X), Z;
  return R;
}

bool holes_symmetric_in_x(const NailModel& nail) {
  for (const auto& h : nail.holes) {
    bool found = false;
    for (const auto& o : nail.holes)
      found = found || (std::abs(o.center_mm.x() + h.center_mm.x()) < 0.01 && std::abs(o.diameter_mm - h.diameter_mm) < 0.01);
    if (!found) return false;
  }
  return true;
}

// The image of the nail near its holes as a function of the pose and the image's blur; the
// per-window background (a + b s + c t + d t^2 in the window's along/across coordinates) and the
// common contrast are solved linearly at each evaluation (variable projection). The chords are
// computed on each window's full pixel grid so that they can be blurred (a Gaussian of the
// fitted width, on the line integrals: the detector's and the focal spot's blur), then the pixels
// in use are gathered.
struct NailWindow {
  int u0, v0, w, h;
  std::vector<std::vector<Eigen::Vector3d>> rays;  // per grid pixel, row-major
};
struct NailImageFit : Eigen::DenseFunctor<double> {
  const NailModel& nail;
  Eigen::Matrix3d R0;
  Eigen::Vector3d t0;
  std::vector<NailWindow> windows;
  std::vector<std::pair<int, int>> used;  // (window, grid index) of each residual
  Eigen::MatrixXd basis;                  // per residual, the background's linear terms
  Eigen::VectorXd observed;

  NailImageFit(const NailModel& n, int pixels) : DenseFunctor<double>(8, pixels), nail(n) {}
  int values() const { return int(observed.size()); }  // pixels in use: fewer after trimming

  // Rays per pixel for a pose near `T`: 16 (4 x 4) where an edge of the nail's image (the
  // silhouette, a hole's rim, the lens's partial-chord border) is within 2 pixels, one elsewhere.
  // Fixed for one Levenberg-Marquardt run, so the cost stays a smooth function of the pose.
  void adapt_rays(const CameraPose& T, const Eigen::Matrix3d& Kinv) {
    const PlacedNail placed = place_nail(nail, T.linear(), T.translation());
    constexpr int n = 4;
    for (auto& w : windows) {
      std::vector<char> edge(size_t(w.w * w.h), 0);
      std::vector<std::vector<Eigen::Vector3d>> fine(size_t(w.w * w.h));
      for (int v = 0; v < w.h; ++v)
        for (int u = 0; u < w.w; ++u) {
          double lo = HUGE_VAL, hi = -HUGE_VAL;
          auto& r = fine[size_t(v * w.w + u)];
          for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
              const Eigen::Vector3d d =
                  (Kinv * Eigen::Vector3d(w.u0 + u - 0.5 + (i + 0.5) / n, w.v0 + v - 0.5 + (j + 0.5) / n, 1)).normalized();
              const double c = nail_chord_mm(placed, d);
              lo = std::min(lo, c), hi = std::max(hi, c);
              r.push_back(d);
            }
          edge[size_t(v * w.w + u)] = hi - lo > 0.05 * nail.diameter_mm ? 1 : 0;
        }
      w.rays.assign(size_t(w.w * w.h), {});
      for (int v = 0; v < w.h; ++v)
        for (int u = 0; u < w.w; ++u) {
          bool near = false;
          for (int dv = -2; dv <= 2 && !near; ++dv)
            for (int du = -2; du <= 2 && !near; ++du) {
              const int uu = u + du, vv = v + dv;
              near = uu >= 0 && vv >= 0 && uu < w.w && vv < w.h && edge[size_t(vv * w.w + uu)];
            }
          auto& r = w.rays[size_t(v * w.w + u)];
          if (near)
            r = fine[size_t(v * w.w + u)];
          else
            r = {(Kinv * Eigen::Vector3d(w.u0 + u, w.v0 + v, 1)).normalized()};
        }
    }
  }

  CameraPose pose(const InputType& p) const {
    CameraPose T = CameraPose::Identity();
    T.linear() = rotation(p.head<3>()) * R0;
    T.translation() = t0 + p.segment<3>(3);
    return T;
  }
  // -ln of the nail's blurred transmission: blur acts on the photons, before the log.
  Eigen::VectorXd chords(const CameraPose& T, double sigma, double mu) const {
    const PlacedNail placed = place_nail(nail, T.linear(), T.translation());
    std::vector<cv::Mat> grids;
    for (const auto& w : windows) {
      cv::Mat g(w.h, w.w, CV_64F);
      tbb::parallel_for(0, w.h, [&](int v) {
        for (int u = 0; u < w.w; ++u) {
          const auto& rays = w.rays[size_t(v * w.w + u)];
          double trans = 0;
          for (const auto& d : rays) trans += std::exp(-mu * nail_chord_mm(placed, d));
          g.at<double>(v, u) = trans / double(rays.size());
        }
      });
      if (sigma > 0.05) cv::GaussianBlur(g, g, cv::Size(0, 0), sigma, sigma, cv::BORDER_REPLICATE);
      cv::log(g, g);
      g = -g;
      grids.push_back(g);
    }
    Eigen::VectorXd L(Eigen::Index(used.size()));
    for (size_t i = 0; i < used.size(); ++i) {
      const auto& w = windows[size_t(used[i].first)];
      L(Eigen::Index(i)) = grids[size_t(used[i].first)].at<double>(used[i].second / w.w, used[i].second % w.w);
    }
    return L;
  }
  int operator()(const InputType& p, ValueType& f) const {
    const Eigen::VectorXd L = chords(pose(p), std::min(3.0, std::abs(p(6))), std::clamp(std::abs(p(7)), 0.005, 3.0));
    Eigen::MatrixXd A(basis.rows(), basis.cols() + 1);
    A << basis, -L;
    const Eigen::VectorXd coef = A.colPivHouseholderQr().solve(observed);
    f = A * coef - observed;
    return 0;
  }
};

}  // namespace

CameraPose nearest_symmetric_pose(const CameraPose& pose, const NailModel& nail, const Eigen::Vector3d& guide_x,
                                  const Eigen::Vector3d& guide_z) {
  std::vector<Eigen::Matrix3d> turns = {Eigen::Matrix3d::Identity(), Eigen::Vector3d(1, -1, -1).asDiagonal()};
  if (holes_symmetric_in_x(nail)) {
    turns.push_back(Eigen::Vector3d(-1, 1, -1).asDiagonal());
    turns.push_back(Eigen::Vector3d(-1, -1, 1).asDiagonal());
  }
  CameraPose best = pose;
  double score = -1e9;
  for (const auto& S : turns) {
    const Eigen::Matrix3d R = pose.linear() * S;
    const double s = R.col(0).dot(guide_x) + R.col(2).dot(guide_z);
    if (s > score) score = s, best.linear() = R;
  }
  return best;
}

NailPoseEstimate fronto_parallel_nail_pose(const NailDetection& det, const NailModel& nail, const Eigen::Matrix3d& K,
                                           const Eigen::Vector3d& guide_x, const Eigen::Vector3d& guide_z) {
  NailPoseEstimate out;
  if (det.holes.size() != nail.holes.size() || nail.holes.size() < 2) {
    out.failure_reason = "holes not separable";
    return out;
  }
  // Model holes in the order of their x; detections are ordered along the band.
  std::vector<double> xs;
  double d_world = 0, d_image = 0;
  for (const auto& h : nail.holes) xs.push_back(h.center_mm.x()), d_world += h.diameter_mm;
  std::sort(xs.begin(), xs.end());
  for (const auto& e : det.holes) d_image += e.major_px;
  d_world /= double(nail.holes.size());
  d_image /= double(det.holes.size());
  const double f = 0.5 * (K(0, 0) + K(1, 1));
  // z = f d_world / d_image is the depth of what bounds the lens: the hole's far wall, where it
  // leaves the rod (sqrt(R^2 - r^2) beyond the nail's axis at the hole's rim).
  const double r = 0.5 * nail.diameter_mm, rh = 0.5 * d_world;
  const double z = f * d_world / d_image - std::sqrt(std::max(0.0, r * r - rh * rh));
  const Eigen::Matrix3d Kinv = K.inverse();
  std::vector<Eigen::Vector3d> P;
  for (const auto& e : det.holes) P.push_back(z * (Kinv * Eigen::Vector3d(e.centre_px.x(), e.centre_px.y(), 1)));
  const Eigen::Vector3d x = (P.back() - P.front()).normalized();
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < P.size(); ++k) origin += P[k] - xs[k] * x;
  origin /= double(P.size());
  CameraPose T = CameraPose::Identity();
  T.linear() = frame_from_x_z(x, origin);  // hole axes along the ray to the nail's centre
  T.translation() = origin;
  // A turn about the nail's z swaps the holes: resolve x by the guide as the seed does.
  out.T_camera_nail = nearest_symmetric_pose(T, nail, guide_x, guide_z);
  if (!holes_symmetric_in_x(nail) && out.T_camera_nail.linear().col(0).dot(x) < 0) {
    // Unequal holes cannot be swapped: keep the detection's order.
    out.T_camera_nail = T;
  }
  out.ok = true;
  return out;
}

NailPoseEstimate fit_nail_pose(const Image& xray, const NailModel& nail, const Eigen::Matrix3d& K, const CameraPose& start,
                               double band_width_px, const std::vector<DarkCircle>& occluders,
                               const Eigen::Vector3d& guide_x, const Eigen::Vector3d& guide_z) {
  NailPoseEstimate out;
  const Eigen::Matrix3d Kinv = K.inverse();
  // Windows around each hole: the nail's width and a little more on each side.
  // Across, a little past the silhouette only: further out the bone's inner wall (whose profile
  // no low-order polynomial follows) would bias the fit.
  const double half = 0.75 * band_width_px, across_half = 0.62 * band_width_px;
  const Eigen::Vector2d along = [&] {
    const Eigen::Vector3d a = K * (start * Eigen::Vector3d(0, 0, 0)), b = K * (start * Eigen::Vector3d(10, 0, 0));
    return Eigen::Vector2d((b.head<2>() / b.z() - a.head<2>() / a.z()).normalized());
  }();
  const Eigen::Vector2d across(-along.y(), along.x());
  std::vector<Eigen::Vector2d> centres;
  for (const auto& h : nail.holes) centres.push_back(project_pose(K, start, h.center_mm));
  std::vector<NailWindow> windows;
  std::vector<std::pair<int, int>> used;
  std::vector<Eigen::Vector4d> terms;
  std::vector<double> values;
  std::vector<int> window_of;
  for (size_t k = 0; k < centres.size(); ++k) {
    const Eigen::Vector2d c = centres[k];
    if (!c.allFinite()) continue;
    NailWindow w;
    const double reach = half * std::sqrt(2.0) + 4;  // the rotated square and the blur's margin
    w.u0 = std::max(0, int(std::floor(c.x() - reach)));
    w.v0 = std::max(0, int(std::floor(c.y() - reach)));
    w.w = std::min(xray.width - 1, int(std::ceil(c.x() + reach))) - w.u0 + 1;
    w.h = std::min(xray.height - 1, int(std::ceil(c.y() + reach))) - w.v0 + 1;
    if (w.w < 5 || w.h < 5) continue;
    for (int v = w.v0; v < w.v0 + w.h; ++v)
      for (int u = w.u0; u < w.u0 + w.w; ++u) {
        const Eigen::Vector2d q(u, v);
        if (std::abs((q - c).dot(along)) > half || std::abs((q - c).dot(across)) > across_half) continue;
        bool hidden = false;
        for (const auto& o : occluders) hidden = hidden || (q - o.centre_px).norm() < o.radius_px + 2.0;
        if (hidden) continue;
        const int wi = int(windows.size());
        used.push_back({wi, (v - w.v0) * w.w + (u - w.u0)});
        const Eigen::Vector2d d = (q - c) / half;
        const double s = d.dot(along), t = d.dot(across);
        terms.push_back(Eigen::Vector4d(1, s, t, t * t));
        values.push_back(xray.at(u, v));
        window_of.push_back(wi);
      }
    windows.push_back(std::move(w));
  }
  const int nwin = int(windows.size());
  if (used.size() < 50 || nwin < int(nail.holes.size())) {
    out.failure_reason = "holes not separable: too little of the nail visible around its holes";
    return out;
  }
  NailImageFit fit(nail, int(used.size()));
  fit.windows = std::move(windows);
  fit.used = std::move(used);
  fit.basis = Eigen::MatrixXd::Zero(Eigen::Index(terms.size()), 4 * nwin);
  fit.observed.resize(Eigen::Index(terms.size()));
  for (size_t i = 0; i < terms.size(); ++i) {
    fit.basis.block<1, 4>(Eigen::Index(i), 4 * window_of[i]) = terms[i].transpose();
    fit.observed(Eigen::Index(i)) = values[i];
  }

  const auto run = [&](const CameraPose& from, double* rms, int* evals, double* sigma, double* mu) {
    fit.R0 = from.linear();
    fit.t0 = from.translation();
    fit.adapt_rays(from, Kinv);
    Eigen::NumericalDiff<NailImageFit> nd(fit);
    Eigen::LevenbergMarquardt<Eigen::NumericalDiff<NailImageFit>> lm(nd);
    lm.setMaxfev(300);
    lm.setXtol(1e-7);
    lm.setFtol(1e-9);
    Eigen::VectorXd p = Eigen::VectorXd::Zero(8);
    p(6) = *sigma;
    p(7) = *mu;
    lm.minimize(p);
    *sigma = std::min(3.0, std::abs(p(6)));
    *mu = std::clamp(std::abs(p(7)), 0.005, 3.0);
    Eigen::VectorXd f(fit.values());
    fit(p, f);
    if (std::getenv("FLUORO_DEBUG_NAIL")) {
      std::vector<std::pair<double, int>> big;
      for (Eigen::Index i = 0; i < f.size(); ++i) big.push_back({std::abs(f(i)), int(i)});
      std::sort(big.rbegin(), big.rend());
      for (int k = 0; k < 15; ++k) {
        const auto& u = fit.used[size_t(big[size_t(k)].second)];
        const auto& w = fit.windows[size_t(u.first)];
        std::fprintf(stderr, "res %.0f at (%d, %d) win %d st %.2f %.2f\n", f(big[size_t(k)].second), w.u0 + u.second % w.w, w.v0 + u.second / w.w, u.first,
                     fit.basis(big[size_t(k)].second, 4 * u.first + 1), fit.basis(big[size_t(k)].second, 4 * u.first + 2));
      }
      std::fprintf(stderr, "sigma %.3f mu %.4f\n", p(6), p(7));
    }
    *rms = std::sqrt(f.squaredNorm() / double(f.size()));
    *evals += int(lm.nfev());
    return fit.pose(p);
  };
  // The nail's attenuation (per mm, in line-integral units) starts at a titanium nail's.
  double rms = 0, mirror_rms = 0, sigma = 0.7, mu = 0.2;
  // The start's depth (from the band's width, whose edges the blur pulls inwards) can be 10 %
  // off, too far for the fit to recover: a line search along the ray to the nail first, scored by
  // the same cost on single rays per pixel.
  CameraPose from = start;
  {
    fit.R0 = start.linear();
    fit.t0 = start.translation();
    fit.adapt_rays(start, Kinv);
    double best = HUGE_VAL, best_scale = 1.0;
    Eigen::VectorXd p = Eigen::VectorXd::Zero(8), f(fit.values());
    p(6) = sigma;
    p(7) = mu;
    for (double scale = 0.80; scale <= 1.2001; scale += 0.01) {
      p.segment<3>(3) = (scale - 1.0) * start.translation();
      fit(p, f);
      ++out.evaluations;
      if (f.squaredNorm() < best) best = f.squaredNorm(), best_scale = scale;
    }
    from.translation() = best_scale * start.translation();
  }
  CameraPose a = run(from, &rms, &out.evaluations, &sigma, &mu);
  // What the model cannot explain (a sphere or a wire over a hole that no detection reported) is
  // left out: residuals beyond 4 robust sigmas, and their neighbours, then the fit again.
  {
    Eigen::VectorXd p = Eigen::VectorXd::Zero(8), f(fit.values());
    fit.R0 = a.linear();
    fit.adapt_rays(a, Kinv);
    fit.t0 = a.translation();
    p(6) = sigma;
    p(7) = mu;
    fit(p, f);
    std::vector<double> absr(size_t(f.size()));
    for (Eigen::Index i = 0; i < f.size(); ++i) absr[size_t(i)] = std::abs(f(i));
    std::vector<double> sorted = absr;
    std::nth_element(sorted.begin(), sorted.begin() + long(sorted.size() / 2), sorted.end());
    const double cut = 4.0 * 1.4826 * sorted[sorted.size() / 2];
    std::vector<std::vector<char>> bad(fit.windows.size());
    for (size_t w = 0; w < fit.windows.size(); ++w) bad[w].assign(size_t(fit.windows[w].w * fit.windows[w].h), 0);
    for (size_t i = 0; i < absr.size(); ++i)
      if (absr[i] > cut) bad[size_t(fit.used[i].first)][size_t(fit.used[i].second)] = 1;
    std::vector<size_t> keep;
    for (size_t i = 0; i < fit.used.size(); ++i) {
      const auto& w = fit.windows[size_t(fit.used[i].first)];
      const int gu = fit.used[i].second % w.w, gv = fit.used[i].second / w.w;
      bool near_bad = false;
      for (int dv = -1; dv <= 1 && !near_bad; ++dv)
        for (int du = -1; du <= 1 && !near_bad; ++du) {
          const int u = gu + du, v = gv + dv;
          if (u >= 0 && v >= 0 && u < w.w && v < w.h && bad[size_t(fit.used[i].first)][size_t(v * w.w + u)]) near_bad = true;
        }
      if (!near_bad) keep.push_back(i);
    }
    if (keep.size() >= 50 && keep.size() < fit.used.size()) {
      std::vector<std::pair<int, int>> used2;
      Eigen::MatrixXd basis2(Eigen::Index(keep.size()), fit.basis.cols());
      Eigen::VectorXd obs2(Eigen::Index(keep.size()));
      for (size_t k = 0; k < keep.size(); ++k) {
        used2.push_back(fit.used[keep[k]]);
        basis2.row(Eigen::Index(k)) = fit.basis.row(Eigen::Index(keep[k]));
        obs2(Eigen::Index(k)) = fit.observed(Eigen::Index(keep[k]));
      }
      fit.used = std::move(used2);
      fit.basis = std::move(basis2);
      fit.observed = std::move(obs2);
    }
  }
  a = run(a, &rms, &out.evaluations, &sigma, &mu);
  out.attenuation_per_mm = mu;
  out.blur_px = sigma;  // restart at the solution: the rotation vector at zero again
  // The single view's ambiguity: mirroring the hole axes in the plane through the source and the
  // nail's long axis leaves the rod's image unchanged; fit from there too and keep the better.
  const Eigen::Vector3d x = a.linear().col(0), c = a.translation();
  const Eigen::Vector3d m = x.cross(c).normalized();
  const Eigen::Vector3d z = a.linear().col(2), zm = z - 2 * z.dot(m) * m;
  CameraPose mirrored = a;
  mirrored.linear() = frame_from_x_z(x, zm);
  double sigma_b = sigma, mu_b = mu;
  CameraPose b = run(mirrored, &mirror_rms, &out.evaluations, &sigma_b, &mu_b);
  // Equal fits (within 2 %): the image cannot tell them apart; the one nearer the guide is kept.
  const bool tie = std::abs(mirror_rms - rms) < 0.02 * std::max(rms, mirror_rms);
  const auto nearness = [&](const CameraPose& T) {
    const CameraPose s = nearest_symmetric_pose(T, nail, guide_x, guide_z);
    return s.linear().col(2).dot(guide_z);
  };
  const bool take_b = tie ? nearness(b) > nearness(a) : mirror_rms < rms;
  out.T_camera_nail = nearest_symmetric_pose(take_b ? b : a, nail, guide_x, guide_z);
  out.rms = take_b ? mirror_rms : rms;
  out.mirror_rms = take_b ? rms : mirror_rms;
  out.ok = true;
  return out;
}

}  // namespace fluoro
