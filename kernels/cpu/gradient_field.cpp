#include "kernels/cpu/gradient_field.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <vector>

#include "kernels/common/gaussian_derivative.hpp"
#include "kernels/common/resample_geometry.hpp"

namespace fluoro::cpu {
namespace {

// One 1D correlation along `axis`, clamp-to-edge. Loops are arranged so the innermost one runs
// over contiguous memory with the tap weight fixed, which the compiler vectorises.
void correlate_axis(const std::vector<float>& in, std::vector<float>& out, const Eigen::Vector3i& n,
                    int axis, const std::vector<double>& weights) {
  const int r = int(weights.size() / 2);
  const std::vector<float> w(weights.begin(), weights.end());
  const int nx = n.x(), ny = n.y(), nz = n.z();
  const size_t row = size_t(nx), slice = size_t(nx) * size_t(ny);
  if (axis == 0) {
    tbb::parallel_for(0, nz, [&](int k) {
      std::vector<float> line(size_t(nx + 2 * r));
      for (int j = 0; j < ny; ++j) {
        const float* src = in.data() + size_t(k) * slice + size_t(j) * row;
        float* dst = out.data() + size_t(k) * slice + size_t(j) * row;
        for (int q = -r; q < nx + r; ++q) line[size_t(q + r)] = src[std::clamp(q, 0, nx - 1)];
        std::fill(dst, dst + nx, 0.0f);
        for (int o = 0; o <= 2 * r; ++o) {
          const float wo = w[size_t(o)];
          const float* l = line.data() + o;
          for (int x = 0; x < nx; ++x) dst[x] += wo * l[x];
        }
      }
    });
    return;
  }
  // Along y or z: whole x-rows are combined, row by row.
  const int len = axis == 1 ? ny : nz, other = axis == 1 ? nz : ny;
  const size_t stride = axis == 1 ? row : slice, other_stride = axis == 1 ? slice : row;
  tbb::parallel_for(0, other, [&](int b) {
    for (int q = 0; q < len; ++q) {
      float* dst = out.data() + size_t(b) * other_stride + size_t(q) * stride;
      std::fill(dst, dst + nx, 0.0f);
      for (int o = -r; o <= r; ++o) {
        const float wo = w[size_t(o + r)];
        const float* src = in.data() + size_t(b) * other_stride + size_t(std::clamp(q + o, 0, len - 1)) * stride;
        for (int x = 0; x < nx; ++x) dst[x] += wo * src[x];
      }
    }
  });
}

}  // namespace

std::shared_ptr<CpuVolume> compute_gradient_field(const CpuVolume& mu, const GradientFieldParams& params,
                                                  const void* owner) {
  const VolumeGeometry& g = mu.geometry();
  const Eigen::Vector3i n = g.size;
  // From the resident (16-bit) voxels: their error, 1.5e-5 of the largest, is far below CT noise.
  const std::vector<float> scalar = mu.unpadded(0);
  DerivativeFilter f[3];
  for (int a = 0; a < 3; ++a) f[a] = make_derivative_filter(params.sigma_mm / g.spacing[a]);
  std::vector<float> d_index[3], tmp(scalar.size());
  for (int axis = 0; axis < 3; ++axis) {
    d_index[axis] = scalar;
    for (int pass = 0; pass < 3; ++pass) {
      correlate_axis(d_index[axis], tmp, n, pass, pass == axis ? f[pass].derivative : f[pass].smooth);
      std::swap(d_index[axis], tmp);
    }
  }
  // Index-space derivatives to the CT physical frame: grad = D S^-1 d_index.
  const Eigen::Matrix3f m = (g.direction * g.spacing.cwiseInverse().asDiagonal()).cast<float>();
  std::vector<float> phys[3];
  for (auto& p : phys) p.resize(scalar.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, scalar.size(), 1 << 14), [&](const tbb::blocked_range<size_t>& b) {
    for (size_t v = b.begin(); v != b.end(); ++v) {
      const Eigen::Vector3f d(d_index[0][v], d_index[1][v], d_index[2][v]);
      const Eigen::Vector3f p = m * d;
      phys[0][v] = p.x();
      phys[1][v] = p.y();
      phys[2][v] = p.z();
    }
  });
  auto grad = std::make_shared<CpuVolume>(g, owner, std::vector<const float*>{phys[0].data(), phys[1].data(), phys[2].data()});
  if (params.resample_spacing_mm <= 0) return grad;

  const VolumeGeometry dst = isotropic_geometry(g, params.resample_spacing_mm);
  // Maps destination index to source index: S_src^-1 D^T (o_dst - o_src) + (s_dst / S_src) ijk.
  const Eigen::Vector3d offset = g.physical_to_index(dst.origin);
  const Eigen::Vector3d scale = Eigen::Vector3d::Constant(params.resample_spacing_mm).cwiseQuotient(g.spacing);
  std::vector<float> out[3];
  for (auto& o : out) o.resize(dst.voxel_count());
  tbb::parallel_for(0, dst.size.z(), [&](int k) {
    for (int j = 0; j < dst.size.y(); ++j)
      for (int i = 0; i < dst.size.x(); ++i) {
        const Eigen::Vector3d x = offset + scale.cwiseProduct(Eigen::Vector3d(i, j, k));
        const size_t v = dst.linear_index(i, j, k);
        for (int c = 0; c < 3; ++c) out[c][v] = grad->sample(c, float(x.x()), float(x.y()), float(x.z()));
      }
  });
  return std::make_shared<CpuVolume>(dst, owner, std::vector<const float*>{out[0].data(), out[1].data(), out[2].data()});
}

}  // namespace fluoro::cpu
