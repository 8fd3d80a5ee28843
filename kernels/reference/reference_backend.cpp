// The reference backend: scalar double-precision loops written to be obviously correct. It is the
// oracle the other backends are tested against, not a fast path.
#include <algorithm>
#include <cmath>
#include <numbers>

#include "engine/backend.hpp"
#include "engine/ray_setup.hpp"
#include "kernels/common/gaussian_derivative.hpp"
#include "kernels/common/resample_geometry.hpp"

namespace fluoro {
namespace {

class ReferenceVolume final : public DeviceVolume {
 public:
  ReferenceVolume(VolumeGeometry g, int components, const void* owner)
      : DeviceVolume(g, components, owner), data(g.voxel_count() * size_t(components)) {}
  std::vector<double> data;  // components interleaved per voxel

  double voxel(int i, int j, int k, int c) const {
    const auto& n = geometry().size;
    i = std::clamp(i, 0, n.x() - 1);
    j = std::clamp(j, 0, n.y() - 1);
    k = std::clamp(k, 0, n.z() - 1);
    return data[geometry().linear_index(i, j, k) * size_t(components()) + size_t(c)];
  }
  // The voxel nearest a continuous index (clamp-to-edge).
  double nearest(const Eigen::Vector3d& x, int c) const {
    return voxel(int(std::floor(x.x() + 0.5)), int(std::floor(x.y() + 0.5)), int(std::floor(x.z() + 0.5)), c);
  }
  // Trilinear at a continuous index, edge voxels extended (clamp-to-edge).
  double sample(const Eigen::Vector3d& x, int c) const {
    const int i = int(std::floor(x.x())), j = int(std::floor(x.y())), k = int(std::floor(x.z()));
    const double fx = x.x() - i, fy = x.y() - j, fz = x.z() - k;
    double v = 0;
    for (int dk = 0; dk < 2; ++dk)
      for (int dj = 0; dj < 2; ++dj)
        for (int di = 0; di < 2; ++di)
          v += (di ? fx : 1 - fx) * (dj ? fy : 1 - fy) * (dk ? fz : 1 - fz) *
               voxel(i + di, j + dj, k + dk, c);
    return v;
  }
};

// Expected gradient (d DRR/du, d DRR/dv) of one pixel: (1/|d|) * integral of t * grad mu . axis.
Eigen::Vector2d project_gradient(const ReferenceVolume& g, const RaySetup& s, double u, double v,
                                 const ProjectionParams& params) {
  const PixelRay r = make_pixel_ray(s, u, v, params.step_mm);
  Eigen::Vector3d acc = Eigen::Vector3d::Zero();
  for (int k = 0; k < r.n; ++k) {
    const double t = r.t0 + (k + 0.5) * r.h;
    const Eigen::Vector3d x = s.source + t * r.dir;
    if (params.sampling == Sampling::nearest)
      acc += t * Eigen::Vector3d(g.nearest(x, 0), g.nearest(x, 1), g.nearest(x, 2));
    else
      acc += t * Eigen::Vector3d(g.sample(x, 0), g.sample(x, 1), g.sample(x, 2));
  }
  acc *= r.h * r.inv_len;
  return {acc.dot(s.axis_u), acc.dot(s.axis_v)};
}

// One 1D correlation along `axis` with clamp-to-edge borders.
std::vector<double> correlate_axis(const std::vector<double>& in, const Eigen::Vector3i& n, int axis,
                                   const std::vector<double>& w) {
  const int r = int(w.size() / 2);
  std::vector<double> out(in.size());
  const size_t stride[3] = {1, size_t(n.x()), size_t(n.x()) * size_t(n.y())};
  for (int k = 0; k < n.z(); ++k)
    for (int j = 0; j < n.y(); ++j)
      for (int i = 0; i < n.x(); ++i) {
        const int pos[3] = {i, j, k};
        const size_t centre = size_t(i) * stride[0] + size_t(j) * stride[1] + size_t(k) * stride[2];
        const size_t base = centre - size_t(pos[axis]) * stride[axis];
        double acc = 0;
        for (int o = -r; o <= r; ++o) {
          const int q = std::clamp(pos[axis] + o, 0, n[axis] - 1);
          acc += w[size_t(o + r)] * in[base + size_t(q) * stride[axis]];
        }
        out[centre] = acc;
      }
  return out;
}

class ReferenceBackend final : public Backend {
 public:
  std::string_view name() const override { return "reference"; }
  bool supports(Op) const override { return true; }

  std::shared_ptr<const DeviceVolume> upload_impl(const Volume& mu) override {
    validate_volume(mu, "reference.upload");
    auto v = std::make_shared<ReferenceVolume>(mu.geometry, 1, this);
    std::copy(mu.voxels.begin(), mu.voxels.end(), v->data.begin());
    return v;
  }

  std::shared_ptr<const DeviceVolume> upload_impl(const VectorField& f) override {
    auto v = std::make_shared<ReferenceVolume>(f.geometry, 3, this);
    for (size_t n = 0; n < f.vectors.size(); ++n)
      for (int c = 0; c < 3; ++c) v->data[3 * n + size_t(c)] = f.vectors[n][size_t(c)];
    return v;
  }

  VectorField download_gradient_impl(const DeviceVolume& handle) override {
    const auto& v = static_cast<const ReferenceVolume&>(handle);
    VectorField f{v.geometry(), VectorBuffer(v.geometry().voxel_count())};
    for (size_t n = 0; n < f.vectors.size(); ++n)
      for (int c = 0; c < 3; ++c) f.vectors[n][size_t(c)] = float(v.data[3 * n + size_t(c)]);
    return f;
  }

  // The definition of Op::gradient_floor (engine/ops.hpp), in double precision.
  std::shared_ptr<const DeviceVolume> floor_gradient_impl(const DeviceVolume& handle,
                                                          const GradientFloorParams& params) override {
    const auto& g = static_cast<const ReferenceVolume&>(handle);
    auto out = std::make_shared<ReferenceVolume>(g.geometry(), 3, this);
    out->data = g.data;
    auto squared = [&](size_t n) {
      const double* v = out->data.data() + 3 * n;
      return v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    };
    const size_t voxels = g.geometry().voxel_count();
    double max_squared = 0;
    for (size_t n = 0; n < voxels; ++n) max_squared = std::max(max_squared, squared(n));
    const double floor_squared = max_squared * params.relative_tolerance * params.relative_tolerance;
    for (size_t n = 0; n < voxels; ++n)
      if (squared(n) < floor_squared) std::fill_n(out->data.data() + 3 * n, 3, 0.0);
    return out;
  }

  std::shared_ptr<const DeviceVolume> gradient_field_impl(const DeviceVolume& handle,
                                                     const GradientFieldParams& params) override {
    const auto& mu = static_cast<const ReferenceVolume&>(handle);
    const VolumeGeometry& g = mu.geometry();
    auto grad = std::make_shared<ReferenceVolume>(g, 3, this);
    DerivativeFilter f[3];
    for (int a = 0; a < 3; ++a) f[a] = make_derivative_filter(params.sigma_mm / g.spacing[a]);
    std::vector<double> scalar(mu.data);
    // Separable: the derivative along one axis, the Gaussian along the other two.
    std::vector<double> d_index[3];
    for (int axis = 0; axis < 3; ++axis) {
      d_index[axis] = scalar;
      for (int pass = 0; pass < 3; ++pass)
        d_index[axis] = correlate_axis(d_index[axis], g.size, pass,
                                       pass == axis ? f[pass].derivative : f[pass].smooth);
    }
    // Index-space derivatives to the CT physical frame: grad = D S^-1 d_index.
    for (size_t n = 0; n < g.voxel_count(); ++n) {
      const Eigen::Vector3d d(d_index[0][n], d_index[1][n], d_index[2][n]);
      const Eigen::Vector3d phys = g.direction * d.cwiseQuotient(g.spacing);
      for (int c = 0; c < 3; ++c) grad->data[3 * n + size_t(c)] = phys[c];
    }
    if (params.resample_spacing_mm <= 0) return grad;
    return resample(*grad, params.resample_spacing_mm, params.keep_coarser_axes);
  }

  std::vector<Image> drr_impl(const DeviceVolume& handle, std::span<const Pose> poses,
                         std::span<const PinholeCamera> views, const DrrParams& params) override {
    const auto& mu = static_cast<const ReferenceVolume&>(handle);
    std::vector<Image> out;
    for (const Pose& pose : poses)
      for (const PinholeCamera& cam : views) {
        const PixelWindow w = resolve_window(params.window, cam);
        const RaySetup s = make_ray_setup(mu.geometry(), pose, cam);
        Image img(w.width, w.height);
        for (int y = 0; y < w.height; ++y)
          for (int x = 0; x < w.width; ++x) {
            const PixelRay r = make_pixel_ray(s, w.x0 + x, w.y0 + y, params.step_mm);
            double sum = 0;
            for (int k = 0; k < r.n; ++k) sum += mu.sample(s.source + (r.t0 + (k + 0.5) * r.h) * r.dir, 0);
            img.at(x, y) = float(sum * r.h);
          }
        out.push_back(std::move(img));
      }
    return out;
  }

  std::vector<std::vector<Eigen::Vector2f>> gradient_projection_impl(
      const DeviceVolume& handle, std::span<const Pose> poses, std::span<const PinholeCamera> views,
      std::span<const std::vector<Eigen::Vector2f>> pixels, const ProjectionParams& params) override {
    const auto& g = static_cast<const ReferenceVolume&>(handle);
    std::vector<std::vector<Eigen::Vector2f>> out;
    for (const Pose& pose : poses)
      for (size_t v = 0; v < views.size(); ++v) {
        const RaySetup s = make_ray_setup(g.geometry(), pose, views[v]);
        std::vector<Eigen::Vector2f> row;
        for (const auto& p : pixels[v])
          row.push_back(project_gradient(g, s, p.x(), p.y(), params).cast<float>());
        out.push_back(std::move(row));
      }
    return out;
  }

  std::vector<double> gpr_score_impl(const DeviceVolume& handle, std::span<const Pose> poses,
                                std::span<const PinholeCamera> views,
                                std::span<const EdgePixels> edges, const GprParams& params) override {
    const auto& g = static_cast<const ReferenceVolume&>(handle);
    const double cos_max = std::cos(params.max_angle_deg * std::numbers::pi / 180.0);
    std::vector<double> scores;
    for (const Pose& pose : poses) {
      double score = 0;
      for (size_t v = 0; v < views.size(); ++v) {
        const RaySetup s = make_ray_setup(g.geometry(), pose, views[v]);
        for (size_t i = 0; i < edges[v].pixels.size(); ++i) {
          const Eigen::Vector2f& p = edges[v].pixels[i];
          const Eigen::Vector2d e = project_gradient(g, s, p.x(), p.y(), params.projection);
          const double m = e.norm();
          if (m > 0 && e.dot(edges[v].directions[i].cast<double>()) >= cos_max * m) score += m;
        }
      }
      scores.push_back(score);
    }
    return scores;
  }

 private:
  std::shared_ptr<const DeviceVolume> resample(const ReferenceVolume& grad, double spacing, bool keep_coarser_axes) {
    const VolumeGeometry& src = grad.geometry();
    const VolumeGeometry dst = resampled_geometry(src, spacing, keep_coarser_axes);
    auto out = std::make_shared<ReferenceVolume>(dst, 3, this);
    for (int k = 0; k < dst.size.z(); ++k)
      for (int j = 0; j < dst.size.y(); ++j)
        for (int i = 0; i < dst.size.x(); ++i) {
          const Eigen::Vector3d x = src.physical_to_index(dst.index_to_physical(Eigen::Vector3d(i, j, k)));
          const size_t n = dst.linear_index(i, j, k);
          for (int c = 0; c < 3; ++c) out->data[3 * n + size_t(c)] = grad.sample(x, c);
        }
    return out;
  }
};

}  // namespace

std::unique_ptr<Backend> make_reference_backend() { return std::make_unique<ReferenceBackend>(); }
}  // namespace fluoro
