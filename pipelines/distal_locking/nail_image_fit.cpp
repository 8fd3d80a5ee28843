#include "pipelines/distal_locking/nail_image_fit.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <tbb/parallel_for.h>
#include <Eigen/Cholesky>
#include <Eigen/QR>

#include "engine/nail_chord.hpp"
#include "engine/pose.hpp"

namespace fluoro {

namespace {

constexpr double kMaxBlurPx = 1.5;
constexpr int kBlurReach = 6;  // OpenCV's kernel radius at the largest blur

}  // namespace

// Declared in the header, so not in the anonymous namespace, and neither may its members' types be
// (-Wsubobject-linkage): the window is its own.
struct NailFitData {
  struct Window {
    int u0, v0, w, h;
    std::vector<char> active;                        // a residual's pixel or within the blur's reach of one
    std::vector<std::vector<Eigen::Vector3d>> rays;  // per grid pixel, row-major
  };
  NailModel nail;
  Eigen::Matrix3d Kinv;
  double band_width_px = 0;
  std::vector<Window> windows;
  std::vector<std::pair<int, int>> used;  // (window, grid index) of each residual
  Eigen::MatrixXd basis;                  // per residual, the background's linear terms
  Eigen::VectorXd observed;
  // The background's part solved once: an orthonormal basis Q of its terms' span and the
  // observation's part orthogonal to it; each evaluation then only projects its line integrals.
  Eigen::MatrixXd Q;
  Eigen::VectorXd observed_perp;
  bool coarse = true;  // rays: one per pixel (or 2 x 2), or supersampled near edges
  void factor_basis() {
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(basis);
    Q = qr.householderQ() * Eigen::MatrixXd::Identity(basis.rows(), qr.rank());
    observed_perp = observed - Q * (Q.transpose() * observed);
  }

  // -ln of the nail's blurred transmission at every residual's pixel, and with `dL` its derivatives
  // (one column per parameter: a rotation about the nail's origin and a translation, both in the
  // camera frame, then with 8 columns the blur and the attenuation). The chords' derivatives are
  // exact (engine/nail_chord.hpp); blurring is linear, so the blurred derivative is the derivative
  // of the blurred transmission; the blur's own by a forward difference of the blur alone.
  Eigen::VectorXd line_integrals(const CameraPose& T, const NailImaging& im, Eigen::MatrixXd* dL = nullptr,
                                 int columns = 0) const {
    const PlacedNail placed = place_nail(nail, T.linear(), T.translation());
    const double sigma = std::min(kMaxBlurPx, std::abs(im.blur_px)), mu = std::clamp(std::abs(im.attenuation_per_mm), kMinNailAttenuationPerMm, kMaxNailAttenuationPerMm);
    const int pose_and_mu = dL ? 7 : 0;  // derivative grids besides the transmission
    std::vector<std::vector<cv::Mat>> grids;  // per window: transmission, then 6 pose, attenuation, blur
    const auto blur = [](const cv::Mat& in, double s) {
      cv::Mat out;
      if (s > 0.05) cv::GaussianBlur(in, out, cv::Size(0, 0), s, s, cv::BORDER_REPLICATE);
      else out = in.clone();
      return out;
    };
    for (const auto& w : windows) {
      std::vector<cv::Mat> g(size_t(1 + pose_and_mu));
      g[0] = cv::Mat(w.h, w.w, CV_64F, cv::Scalar(1.0));
      for (int k = 1; k <= pose_and_mu; ++k) g[size_t(k)] = cv::Mat(w.h, w.w, CV_64F, cv::Scalar(0.0));
      tbb::parallel_for(0, w.h, [&](int v) {
        Eigen::Matrix<double, 6, 1> grad;
        for (int u = 0; u < w.w; ++u) {
          const auto& rays = w.rays[size_t(v * w.w + u)];
          if (rays.empty()) continue;
          const double inv = 1.0 / double(rays.size());
          if (!pose_and_mu) {
            double t = 0;
            for (const auto& d : rays) t += std::exp(-mu * nail_chord_mm(placed, d));
            g[0].at<double>(v, u) = t * inv;
            continue;
          }
          double t = 0, dmu = 0;
          Eigen::Matrix<double, 6, 1> dpose = Eigen::Matrix<double, 6, 1>::Zero();
          for (const auto& d : rays) {
            const double c = nail_chord_gradient(placed, d, &grad);
            const double e = std::exp(-mu * c);
            t += e;
            if (c > 0) dpose -= (mu * e) * grad, dmu -= c * e;
          }
          g[0].at<double>(v, u) = t * inv;
          for (int k = 0; k < 6; ++k) g[size_t(1 + k)].at<double>(v, u) = dpose(k) * inv;
          g[7].at<double>(v, u) = dmu * inv;
        }
      });
      std::vector<cv::Mat> b;
      for (const auto& m : g) b.push_back(blur(m, sigma));
      if (dL && columns == 8) {
        constexpr double h = 0.02;
        b.push_back((blur(g[0], std::min(kMaxBlurPx + h, sigma + h)) - b[0]) / h);
      }
      grids.push_back(std::move(b));
    }
    Eigen::VectorXd L(Eigen::Index(used.size()));
    if (dL) dL->resize(Eigen::Index(used.size()), columns);
    for (size_t i = 0; i < used.size(); ++i) {
      const auto& w = windows[size_t(used[i].first)];
      const auto& b = grids[size_t(used[i].first)];
      const int v = used[i].second / w.w, u = used[i].second % w.w;
      const double t = b[0].at<double>(v, u);
      L(Eigen::Index(i)) = -std::log(t);
      if (!dL) continue;
      for (int k = 0; k < 6; ++k) (*dL)(Eigen::Index(i), k) = -b[size_t(1 + k)].at<double>(v, u) / t;
      if (columns == 8) {
        // The parameters are |blur| and |attenuation|; both stay positive in the fit.
        (*dL)(Eigen::Index(i), 6) = -b[8].at<double>(v, u) / t;
        (*dL)(Eigen::Index(i), 7) = -b[7].at<double>(v, u) / t;
      }
    }
    return L;
  }
  // Variable projection: the residual of the best background and contrast, r = -(P_perp(A) y) for
  // A = [background terms, -L]; with P_B the background's projector, l = (I - P_B) L and
  // y' = (I - P_B) y, r = l (l.y')/(l.l) - y'.
  Eigen::VectorXd residuals(const CameraPose& T, const NailImaging& im) const {
    const Eigen::VectorXd L = line_integrals(T, im);
    const Eigen::VectorXd l = L - Q * (Q.transpose() * L);
    const double ll = l.squaredNorm();
    if (!(ll > 0)) return -observed_perp;
    return l * (l.dot(observed_perp) / ll) - observed_perp;
  }
  // Residuals and their Jacobian (Kaufman's variable-projection approximation: J = P_perp(A)
  // dA/dp coef, dA/dp's only non-zero column the contrast's, -dL/dp, its coefficient -(l.y')/(l.l)).
  Eigen::VectorXd residuals(const CameraPose& T, const NailImaging& im, int columns, Eigen::MatrixXd* J) const {
    Eigen::MatrixXd dL;
    const Eigen::VectorXd L = line_integrals(T, im, &dL, columns);
    const Eigen::VectorXd l = L - Q * (Q.transpose() * L);
    const double ll = std::max(l.squaredNorm(), 1e-300);
    const double contrast = -l.dot(observed_perp) / ll;
    Eigen::MatrixXd D = (-contrast) * dL;
    D -= Q * (Q.transpose() * D);
    const Eigen::VectorXd lhat = l / std::sqrt(ll);
    D -= lhat * (lhat.transpose() * D);
    *J = std::move(D);
    return l * (l.dot(observed_perp) / ll) - observed_perp;
  }
};


NailImageModel::NailImageModel(const Image& xray, const NailModel& nail, const Eigen::Matrix3d& K, const CameraPose& around,
                               double band_width_px, const std::vector<DarkCircle>& occluders)
    : data_(std::make_shared<NailFitData>()) {
  NailFitData& d = *data_;
  d.nail = nail;
  d.Kinv = K.inverse();
  d.band_width_px = band_width_px;
  const double half = 0.75 * band_width_px, across_half = 0.62 * band_width_px;
  const Eigen::Vector2d a = project_pose(K, around, Eigen::Vector3d::Zero()), b = project_pose(K, around, Eigen::Vector3d(10, 0, 0));
  const Eigen::Vector2d along = (b - a).normalized(), across(-along.y(), along.x());
  std::vector<Eigen::Vector4d> terms;
  std::vector<double> values;
  std::vector<int> window_of;
  for (const auto& hole : nail.holes) {
    const Eigen::Vector2d c = project_pose(K, around, hole.center_mm);
    if (!c.allFinite()) continue;
    NailFitData::Window w;
    const double reach = half * std::sqrt(2.0) + kBlurReach;
    w.u0 = std::max(0, int(std::floor(c.x() - reach)));
    w.v0 = std::max(0, int(std::floor(c.y() - reach)));
    w.w = std::min(xray.width - 1, int(std::ceil(c.x() + reach))) - w.u0 + 1;
    w.h = std::min(xray.height - 1, int(std::ceil(c.y() + reach))) - w.v0 + 1;
    if (w.w < 5 || w.h < 5) continue;
    w.active.assign(size_t(w.w * w.h), 0);
    w.rays.resize(size_t(w.w * w.h));
    const int wi = int(d.windows.size());
    for (int v = w.v0; v < w.v0 + w.h; ++v)
      for (int u = w.u0; u < w.u0 + w.w; ++u) {
        const Eigen::Vector2d q(u, v);
        const double s = (q - c).dot(along), t = (q - c).dot(across);
        if (std::abs(s) > half + kBlurReach || std::abs(t) > across_half + kBlurReach) continue;
        w.active[size_t((v - w.v0) * w.w + (u - w.u0))] = 1;
        if (std::abs(s) > half || std::abs(t) > across_half) continue;
        bool hidden = false;
        for (const auto& o : occluders) hidden = hidden || (q - o.centre_px).norm() < o.radius_px + 2.0;
        if (hidden) continue;
        d.used.push_back({wi, (v - w.v0) * w.w + (u - w.u0)});
        terms.push_back(Eigen::Vector4d(1, s / half, t / half, (t / half) * (t / half)));
        values.push_back(xray.at(u, v));
        window_of.push_back(wi);
      }
    d.windows.push_back(std::move(w));
  }
  d.basis = Eigen::MatrixXd::Zero(Eigen::Index(terms.size()), 4 * Eigen::Index(d.windows.size()));
  d.observed.resize(Eigen::Index(terms.size()));
  for (size_t i = 0; i < terms.size(); ++i) {
    d.basis.block<1, 4>(Eigen::Index(i), 4 * window_of[i]) = terms[i].transpose();
    d.observed(Eigen::Index(i)) = values[i];
  }
  if (!d.used.empty()) d.factor_basis();
}

NailImageModel::~NailImageModel() = default;

bool NailImageModel::usable() const {
  return data_->windows.size() == data_->nail.holes.size() && data_->used.size() >= 50;
}

int NailImageModel::residual_count() const { return int(data_->used.size()); }


void NailImageModel::set_rays(const CameraPose& T, bool coarse) {
  NailFitData& d = *data_;
  d.coarse = coarse;
  const PlacedNail placed = place_nail(d.nail, T.linear(), T.translation());
  const int n = d.band_width_px > 30 ? 3 : 4;
  for (auto& w : d.windows) {
    const auto grid_rays = [&](int u, int v, int m) {
      std::vector<Eigen::Vector3d> r;
      for (int j = 0; j < m; ++j)
        for (int i = 0; i < m; ++i)
          r.push_back((d.Kinv * Eigen::Vector3d(w.u0 + u - 0.5 + (i + 0.5) / m, w.v0 + v - 0.5 + (j + 0.5) / m, 1)).normalized());
      return r;
    };
    const auto centre_ray = [&](int u, int v) { return grid_rays(u, v, 1); };
    if (coarse) {
      // Below 30 px across the band a single ray per pixel misreads the holes' rims by too much
      // (the fit then finds wrong minima): 2 x 2 there.
      const int m = d.band_width_px > 30 ? 1 : 2;
      for (int v = 0; v < w.h; ++v)
        for (int u = 0; u < w.w; ++u)
          w.rays[size_t(v * w.w + u)] = w.active[size_t(v * w.w + u)] ? grid_rays(u, v, m) : std::vector<Eigen::Vector3d>{};
      continue;
    }
    // Where does the chord change within a pixel? Sampled on the fine grid itself.
    std::vector<char> edge(size_t(w.w * w.h), 0);
    std::vector<std::vector<Eigen::Vector3d>> fine(size_t(w.w * w.h));
    tbb::parallel_for(0, w.h, [&](int v) {
      for (int u = 0; u < w.w; ++u) {
        if (!w.active[size_t(v * w.w + u)]) continue;
        double lo = HUGE_VAL, hi = -HUGE_VAL;
        auto& r = fine[size_t(v * w.w + u)];
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i) {
            const Eigen::Vector3d ray =
                (d.Kinv * Eigen::Vector3d(w.u0 + u - 0.5 + (i + 0.5) / n, w.v0 + v - 0.5 + (j + 0.5) / n, 1)).normalized();
            const double c = nail_chord_mm(placed, ray);
            lo = std::min(lo, c), hi = std::max(hi, c);
            r.push_back(ray);
          }
        edge[size_t(v * w.w + u)] = hi - lo > 0.05 * d.nail.diameter_mm ? 1 : 0;
      }
    });
    for (int v = 0; v < w.h; ++v)
      for (int u = 0; u < w.w; ++u) {
        auto& r = w.rays[size_t(v * w.w + u)];
        if (!w.active[size_t(v * w.w + u)]) {
          r.clear();
          continue;
        }
        bool near = false;
        for (int dv = -2; dv <= 2 && !near; ++dv)
          for (int du = -2; du <= 2 && !near; ++du) {
            const int uu = u + du, vv = v + dv;
            near = uu >= 0 && vv >= 0 && uu < w.w && vv < w.h && edge[size_t(vv * w.w + uu)];
          }
        r = near ? std::move(fine[size_t(v * w.w + u)]) : centre_ray(u, v);
      }
  }
}

double NailImageModel::rms(const CameraPose& pose, const NailImaging& imaging) const {
  const Eigen::VectorXd f = data_->residuals(pose, imaging);
  return std::sqrt(f.squaredNorm() / double(std::max<Eigen::Index>(1, f.size())));
}

CameraPose NailImageModel::fit(const CameraPose& from, NailImaging* imaging, bool free_imaging, double* rms_out,
                               int* evaluations) {
  // Levenberg-Marquardt (Marquardt's scaling) with the analytic Jacobian, on the manifold: each step
  // turns the pose about the nail's origin and moves it, from where the last accepted step left it.
  const NailFitData& d = *data_;
  const int k = free_imaging ? 8 : 6;
  CameraPose pose = from;
  NailImaging im = *imaging;
  Eigen::MatrixXd J;
  Eigen::VectorXd r = d.residuals(pose, im, k, &J);
  int evals = 1;
  double cost = r.squaredNorm(), lambda = 1e-3;
  for (int iteration = 0; iteration < 100; ++iteration) {
    const Eigen::MatrixXd H = J.transpose() * J;
    const Eigen::VectorXd g = J.transpose() * r;
    bool accepted = false, converged = false;
    while (!accepted) {
      Eigen::MatrixXd Hd = H;
      for (int i = 0; i < k; ++i) Hd(i, i) += lambda * std::max(H(i, i), 1e-12 * H.diagonal().maxCoeff());
      const Eigen::VectorXd step = Hd.ldlt().solve(-g);
      if (!step.allFinite()) break;
      CameraPose next = pose;
      next.linear() = rotation_from_vector(step.head<3>()) * pose.linear();
      next.translation() = pose.translation() + step.segment<3>(3);
      NailImaging next_im = im;
      if (k == 8)
        next_im = {std::clamp(im.blur_px + step(6), 0.0, kMaxBlurPx), std::clamp(im.attenuation_per_mm + step(7), kMinNailAttenuationPerMm, kMaxNailAttenuationPerMm)};
      // A trial costs the residuals only; the Jacobian is computed where a step is accepted.
      const Eigen::VectorXd rn = d.residuals(next, next_im);
      ++evals;
      const double cn = rn.squaredNorm();
      const bool tiny = step.head<3>().norm() < 1e-7 && step.segment<3>(3).norm() < 1e-4;
      if (cn < cost) {
        // The coarse fit only seeds the fine one: stopped at a relative decrease of 1e-6.
        converged = tiny || cost - cn < (d.coarse ? 1e-6 : 1e-9) * cost;
        pose = next, im = next_im, cost = cn;
        if (!converged) {
          r = d.residuals(pose, im, k, &J);
          ++evals;
        }
        lambda = std::max(lambda / 3.0, 1e-9);
        accepted = true;
      } else {
        // A rejected step that changes the sum of squares by under 1e-6 of it is below what the
        // Jacobian (capped near tangents, Kaufman's approximation) resolves: with ~10^4 residuals,
        // 0.01 noise variances, a pose within 0.1 standard errors of the minimum. Stop there
        // rather than raise the damping through another dozen trials.
        lambda *= 4.0;
        if (tiny || lambda > 1e8 || cn - cost < 1e-6 * cost) break;
      }
    }
    if (!accepted || converged) break;
  }
  if (evaluations) *evaluations += evals;
  *imaging = im;
  if (rms_out) *rms_out = std::sqrt(cost / double(std::max<Eigen::Index>(1, r.size())));
  return pose;
}

void NailImageModel::trim(const CameraPose& pose, const NailImaging& imaging) {
  NailFitData& d = *data_;
  const Eigen::VectorXd f = d.residuals(pose, imaging);
  std::vector<double> a(size_t(f.size()));
  for (Eigen::Index i = 0; i < f.size(); ++i) a[size_t(i)] = std::abs(f(i));
  std::vector<double> sorted = a;
  std::nth_element(sorted.begin(), sorted.begin() + long(sorted.size() / 2), sorted.end());
  const double cut = 4.0 * 1.4826 * sorted[sorted.size() / 2];
  std::vector<std::vector<char>> bad(d.windows.size());
  for (size_t w = 0; w < d.windows.size(); ++w) bad[w].assign(size_t(d.windows[w].w * d.windows[w].h), 0);
  for (size_t i = 0; i < a.size(); ++i)
    if (a[i] > cut) bad[size_t(d.used[i].first)][size_t(d.used[i].second)] = 1;
  std::vector<size_t> keep;
  for (size_t i = 0; i < d.used.size(); ++i) {
    const auto& w = d.windows[size_t(d.used[i].first)];
    const int gu = d.used[i].second % w.w, gv = d.used[i].second / w.w;
    bool near_bad = false;
    for (int dv = -1; dv <= 1 && !near_bad; ++dv)
      for (int du = -1; du <= 1 && !near_bad; ++du) {
        const int u = gu + du, v = gv + dv;
        near_bad = u >= 0 && v >= 0 && u < w.w && v < w.h && bad[size_t(d.used[i].first)][size_t(v * w.w + u)];
      }
    if (!near_bad) keep.push_back(i);
  }
  if (keep.size() < 50 || keep.size() == d.used.size()) return;
  std::vector<std::pair<int, int>> used;
  Eigen::MatrixXd basis(Eigen::Index(keep.size()), d.basis.cols());
  Eigen::VectorXd observed(Eigen::Index(keep.size()));
  for (size_t k = 0; k < keep.size(); ++k) {
    used.push_back(d.used[keep[k]]);
    basis.row(Eigen::Index(k)) = d.basis.row(Eigen::Index(keep[k]));
    observed(Eigen::Index(k)) = d.observed(Eigen::Index(keep[k]));
  }
  d.used = std::move(used);
  d.basis = std::move(basis);
  d.observed = std::move(observed);
  d.factor_basis();
}

}  // namespace fluoro
