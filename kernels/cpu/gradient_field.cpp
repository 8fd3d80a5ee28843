#include "kernels/cpu/gradient_field.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "kernels/common/gaussian_derivative.hpp"
#include "kernels/common/resample_geometry.hpp"
#include "kernels/cpu/default_init_allocator.hpp"

namespace fluoro::cpu {
namespace {

// One axis of the field: the Gaussian (or its derivative) along the CT's axis, then linear
// interpolation at the output grid's positions along it. Both are linear and act along one axis,
// and trilinear interpolation is the product of three such interpolations, so filtering the
// whole CT and then resampling it trilinearly (what the reference backend does) equals three
// passes of these 1D kernels, each of which shrinks its axis to the output grid's size. Output
// sample p is sum_t weight[p * taps + t] * in[first[p] + t]; clamp-to-edge of the filter and of
// the interpolation nodes is folded into the weights.
struct AxisKernel {
  int taps = 0;
  std::vector<int> first;
  std::vector<float> weight;
};

// Output p sits at source index offset + scale * p (scale 1, offset 0: no resampling).
AxisKernel axis_kernel(int n_src, int n_dst, double offset, double scale, const std::vector<double>& filter) {
  const int r = int(filter.size() / 2);
  const int taps = std::min(n_src, 2 * r + 2);
  AxisKernel k;
  k.taps = taps;
  k.first.resize(size_t(n_dst));
  k.weight.assign(size_t(n_dst) * size_t(taps), 0.0f);
  std::vector<double> dense(static_cast<size_t>(n_src));
  for (int p = 0; p < n_dst; ++p) {
    const double x = offset + scale * p;
    const double i0 = std::floor(x), f = x - i0;
    std::fill(dense.begin(), dense.end(), 0.0);
    int lo = n_src, hi = -1;
    const auto node = [&](double i, double wn) {
      if (wn == 0) return;
      const int c = std::clamp(int(i), 0, n_src - 1);
      for (int o = -r; o <= r; ++o) {
        const int s = std::clamp(c + o, 0, n_src - 1);
        dense[size_t(s)] += wn * filter[size_t(o + r)];
        lo = std::min(lo, s);
        hi = std::max(hi, s);
      }
    };
    node(std::clamp(i0, -1.0, double(n_src)), 1.0 - f);
    node(std::clamp(i0 + 1, -1.0, double(n_src)), f);
    const int start = std::clamp(lo, 0, n_src - taps);  // hi - lo < taps always
    k.first[size_t(p)] = start;
    for (int t = 0; t < taps; ++t) k.weight[size_t(p) * size_t(taps) + size_t(t)] = float(dense[size_t(start + t)]);
  }
  return k;
}

// rows_out[q] = sum_t w[q][t] * rows_in[first[q] + t] for whole rows of `width` floats: a pass
// along y within a slice, vectorised along x.
void rows_pass(const AxisKernel& k, const float* in, float* out, int n_out, int width) {
  for (int q = 0; q < n_out; ++q) {
    float* dst = out + size_t(q) * size_t(width);
    std::fill(dst, dst + width, 0.0f);
    for (int t = 0; t < k.taps; ++t) {
      const float w = k.weight[size_t(q) * size_t(k.taps) + size_t(t)];
      if (w == 0.0f) continue;
      const float* src = in + size_t(k.first[size_t(q)] + t) * size_t(width);
      for (int x = 0; x < width; ++x) dst[x] += w * src[x];
    }
  }
}

// out[p] = sum_t w[p][t] * in[first[p] + t] along one row (the pass along x).
void row_pass(const AxisKernel& k, const float* in, float* out, int n_out) {
  for (int p = 0; p < n_out; ++p) {
    const float* w = k.weight.data() + size_t(p) * size_t(k.taps);
    const float* s = in + k.first[size_t(p)];
    float acc = 0.0f;
    for (int t = 0; t < k.taps; ++t) acc += w[t] * s[t];
    out[p] = acc;
  }
}

}  // namespace

std::shared_ptr<CpuVolume> compute_gradient_field(const CpuVolume& mu, const GradientFieldParams& params,
                                                  const void* owner) {
  const VolumeGeometry& g = mu.geometry();
  const Eigen::Vector3i n = g.size;
  const bool resample = params.resample_spacing_mm > 0;
  const VolumeGeometry dst = resample ? resampled_geometry(g, params.resample_spacing_mm, params.keep_coarser_axes) : g;
  // Output index to source index along each axis (the grids share their direction).
  const Eigen::Vector3d offset = resample ? g.physical_to_index(dst.origin) : Eigen::Vector3d::Zero();
  const Eigen::Vector3d scale = resample ? Eigen::Vector3d(dst.spacing.cwiseQuotient(g.spacing)) : Eigen::Vector3d::Ones();
  AxisKernel smooth[3], derivative[3];
  for (int a = 0; a < 3; ++a) {
    const DerivativeFilter f = make_derivative_filter(params.sigma_mm / g.spacing[a]);
    smooth[a] = axis_kernel(n[a], dst.size[a], offset[a], scale[a], f.smooth);
    derivative[a] = axis_kernel(n[a], dst.size[a], offset[a], scale[a], f.derivative);
  }
  // The three index-space derivatives share their passes: along z, the Gaussian S_z and the
  // derivative D_z of mu; along y, S_y S_z, D_y S_z and S_y D_z; along x, d/dx = D_x S_y S_z,
  // d/dy = S_x D_y S_z, d/dz = S_x S_y D_z. Eight passes instead of nine, one output slice at a
  // time, so nothing of the CT's size is ever held but the CT itself (read from its resident
  // 16-bit voxels: their error, 1.5e-5 of the largest, is far below CT noise).
  const PaddedGrid grid = mu.grid();
  const int nx = n.x(), ny = n.y(), mx = dst.size.x(), my = dst.size.y();
  const size_t out_count = dst.voxel_count();
  // Written in full below, in parallel: left unzeroed (and on huge pages), so the page faults are
  // taken by the pass that writes them, on both threads, instead of by a zeroing pass on one.
  std::vector<float, DefaultInitAllocator<float>> phys[3];
  for (auto& p : phys) p.resize(out_count);
  // grad = D S^-1 d_index, the CT physical frame.
  const Eigen::Matrix3f m = (g.direction * g.spacing.cwiseInverse().asDiagonal()).cast<float>();
  const float mu_scale = grid.scale[0];
  tbb::parallel_for(0, dst.size.z(), [&](int k) {
    const size_t slice = size_t(nx) * size_t(ny), rows = size_t(nx) * size_t(my), width = static_cast<size_t>(mx);
    std::vector<float> sz(slice), dz(slice), syz(rows), dyz(rows), syd(rows), gx(width), gy(width), gz(width);
    // Along z, from the resident voxels (each word's low half-word is its own voxel).
    std::fill(sz.begin(), sz.end(), 0.0f);
    std::fill(dz.begin(), dz.end(), 0.0f);
    // The smooth and derivative kernels share their taps and first indices (axis_kernel places
    // them by the interpolation nodes alone), so one loop serves both.
    const int kz = smooth[2].taps;
    for (int t = 0; t < kz; ++t) {
      const int z = smooth[2].first[size_t(k)] + t;
      const float ws = smooth[2].weight[size_t(k) * size_t(kz) + size_t(t)] * mu_scale;
      const float wd = derivative[2].weight[size_t(k) * size_t(kz) + size_t(t)] * mu_scale;
      for (int j = 0; j < ny; ++j) {
        const uint64_t* src = grid.words + ((size_t(z + 1) * size_t(grid.ny) + size_t(j + 1)) * size_t(grid.nx) + 1);
        float* s = sz.data() + size_t(j) * size_t(nx);
        float* d = dz.data() + size_t(j) * size_t(nx);
        if (grid.is_signed)
          for (int x = 0; x < nx; ++x) {
            const float v = float(int16_t(uint16_t(src[x] & 0xFFFFu)));
            s[x] += ws * v;
            d[x] += wd * v;
          }
        else
          for (int x = 0; x < nx; ++x) {
            const float v = float(uint32_t(src[x] & 0xFFFFu));
            s[x] += ws * v;
            d[x] += wd * v;
          }
      }
    }
    rows_pass(smooth[1], sz.data(), syz.data(), my, nx);
    rows_pass(derivative[1], sz.data(), dyz.data(), my, nx);
    rows_pass(smooth[1], dz.data(), syd.data(), my, nx);
    for (int j = 0; j < my; ++j) {
      const size_t r = size_t(j) * size_t(nx);
      row_pass(derivative[0], syz.data() + r, gx.data(), mx);
      row_pass(smooth[0], dyz.data() + r, gy.data(), mx);
      row_pass(smooth[0], syd.data() + r, gz.data(), mx);
      const size_t o = dst.linear_index(0, j, k);
      for (int i = 0; i < mx; ++i) {
        const Eigen::Vector3f p = m * Eigen::Vector3f(gx[size_t(i)], gy[size_t(i)], gz[size_t(i)]);
        phys[0][o + size_t(i)] = p.x();
        phys[1][o + size_t(i)] = p.y();
        phys[2][o + size_t(i)] = p.z();
      }
    }
  });
  return std::make_shared<CpuVolume>(dst, owner, std::vector<const float*>{phys[0].data(), phys[1].data(), phys[2].data()});
}

}  // namespace fluoro::cpu
