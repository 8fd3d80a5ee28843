#include "pipelines/distal_locking/nail_image_fit.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <tbb/parallel_for.h>
#include <unsupported/Eigen/LevenbergMarquardt>
#include <unsupported/Eigen/NumericalDiff>

#include "engine/nail_chord.hpp"

namespace fluoro {

namespace {

constexpr double kMaxBlurPx = 1.5;
constexpr int kBlurReach = 6;  // OpenCV's kernel radius at the largest blur

Eigen::Matrix3d rotation(const Eigen::Vector3d& w) {
  const double a = w.norm();
  return a < 1e-300 ? Eigen::Matrix3d::Identity() : Eigen::AngleAxisd(a, w / a).toRotationMatrix();
}

struct Window {
  int u0, v0, w, h;
  std::vector<char> active;                        // a residual's pixel or within the blur's reach of one
  std::vector<std::vector<Eigen::Vector3d>> rays;  // per grid pixel, row-major
};

}  // namespace

struct NailFitData {
  NailModel nail;
  Eigen::Matrix3d Kinv;
  double band_width_px = 0;
  std::vector<Window> windows;
  std::vector<std::pair<int, int>> used;  // (window, grid index) of each residual
  Eigen::MatrixXd basis;                  // per residual, the background's linear terms
  Eigen::VectorXd observed;

  // -ln of the nail's blurred transmission at every residual's pixel.
  Eigen::VectorXd line_integrals(const CameraPose& T, const NailImaging& im) const {
    const PlacedNail placed = place_nail(nail, T.linear(), T.translation());
    const double sigma = std::min(kMaxBlurPx, std::abs(im.blur_px)), mu = std::clamp(std::abs(im.attenuation_per_mm), 0.005, 3.0);
    std::vector<cv::Mat> grids;
    for (const auto& w : windows) {
      cv::Mat g(w.h, w.w, CV_64F, cv::Scalar(1.0));
      tbb::parallel_for(0, w.h, [&](int v) {
        for (int u = 0; u < w.w; ++u) {
          const auto& rays = w.rays[size_t(v * w.w + u)];
          if (rays.empty()) continue;
          double t = 0;
          for (const auto& d : rays) t += std::exp(-mu * nail_chord_mm(placed, d));
          g.at<double>(v, u) = t / double(rays.size());
        }
      });
      if (sigma > 0.05) cv::GaussianBlur(g, g, cv::Size(0, 0), sigma, sigma, cv::BORDER_REPLICATE);
      grids.push_back(g);
    }
    Eigen::VectorXd L(Eigen::Index(used.size()));
    for (size_t i = 0; i < used.size(); ++i) {
      const auto& w = windows[size_t(used[i].first)];
      L(Eigen::Index(i)) = -std::log(grids[size_t(used[i].first)].at<double>(used[i].second / w.w, used[i].second % w.w));
    }
    return L;
  }
  Eigen::VectorXd residuals(const CameraPose& T, const NailImaging& im) const {
    const Eigen::VectorXd L = line_integrals(T, im);
    Eigen::MatrixXd A(basis.rows(), basis.cols() + 1);
    A << basis, -L;
    const Eigen::VectorXd coef = A.colPivHouseholderQr().solve(observed);
    return A * coef - observed;
  }
};

namespace {

// LM parameters: a rotation vector on the left of R0, a translation added to t0, and with 8
// inputs the blur and attenuation.
struct PoseFunctor : Eigen::DenseFunctor<double> {
  const NailFitData* data;
  Eigen::Matrix3d R0;
  Eigen::Vector3d t0;
  NailImaging fixed;
  PoseFunctor(const NailFitData* d, int inputs) : DenseFunctor<double>(inputs, int(d->observed.size())), data(d) {}
  CameraPose pose(const InputType& p) const {
    CameraPose T = CameraPose::Identity();
    T.linear() = rotation(p.head<3>()) * R0;
    T.translation() = t0 + p.segment<3>(3);
    return T;
  }
  NailImaging imaging(const InputType& p) const {
    return inputs() == 8 ? NailImaging{p(6), p(7)} : fixed;
  }
  int operator()(const InputType& p, ValueType& f) const {
    f = data->residuals(pose(p), imaging(p));
    return 0;
  }
};

}  // namespace

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
    Window w;
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
}

NailImageModel::~NailImageModel() = default;

bool NailImageModel::usable() const {
  return data_->windows.size() == data_->nail.holes.size() && data_->used.size() >= 50;
}

int NailImageModel::residual_count() const { return int(data_->used.size()); }

void NailImageModel::set_rays(const CameraPose& T, bool coarse) {
  NailFitData& d = *data_;
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
  PoseFunctor f(data_.get(), free_imaging ? 8 : 6);
  f.R0 = from.linear();
  f.t0 = from.translation();
  f.fixed = *imaging;
  Eigen::NumericalDiff<PoseFunctor> nd(f);
  Eigen::LevenbergMarquardt<Eigen::NumericalDiff<PoseFunctor>> lm(nd);
  lm.setMaxfev(300);
  lm.setXtol(1e-7);
  lm.setFtol(1e-9);
  Eigen::VectorXd p = Eigen::VectorXd::Zero(f.inputs());
  if (free_imaging) p(6) = imaging->blur_px, p(7) = imaging->attenuation_per_mm;
  lm.minimize(p);
  if (evaluations) *evaluations += int(lm.nfev());
  if (free_imaging)
    *imaging = {std::min(kMaxBlurPx, std::abs(p(6))), std::clamp(std::abs(p(7)), 0.005, 3.0)};
  const CameraPose pose = f.pose(p);
  if (rms_out) *rms_out = rms(pose, *imaging);
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
}

}  // namespace fluoro
