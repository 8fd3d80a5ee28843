#include "kernels/cpu/cpu_volume.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace fluoro::cpu {

CpuVolume::CpuVolume(const VolumeGeometry& g, int components, const void* owner)
    : DeviceVolume(g, components, owner), nx_(g.size.x() + 2), ny_(g.size.y() + 2), nz_(g.size.z() + 2) {
  for (int c = 0; c < components; ++c) data_[c].resize(size_t(nx_) * size_t(ny_) * size_t(nz_));
}

void CpuVolume::set_component(int c, const float* src) {
  const auto& n = geometry().size;
  std::vector<float>& dst = data_[c];
  tbb::parallel_for(0, nz_, [&](int kp) {
    const int k = std::clamp(kp - 1, 0, n.z() - 1);
    for (int jp = 0; jp < ny_; ++jp) {
      const int j = std::clamp(jp - 1, 0, n.y() - 1);
      const float* row = src + (size_t(k) * size_t(n.y()) + size_t(j)) * size_t(n.x());
      float* out = dst.data() + padded_index(0, jp, kp);
      out[0] = row[0];
      std::copy(row, row + n.x(), out + 1);
      out[nx_ - 1] = row[n.x() - 1];
    }
  });
}

float CpuVolume::sample(int c, float x, float y, float z) const {
  // Into padded coordinates, clamped to the padded box like the SIMD kernel.
  x = std::clamp(x + 1.0f, 0.0f, float(nx_) - 1.001f);
  y = std::clamp(y + 1.0f, 0.0f, float(ny_) - 1.001f);
  z = std::clamp(z + 1.0f, 0.0f, float(nz_) - 1.001f);
  const int i = int(x), j = int(y), k = int(z);
  const float fx = x - float(i), fy = y - float(j), fz = z - float(k);
  const float* d = data_[c].data() + padded_index(i, j, k);
  const size_t sy = size_t(nx_), sz = size_t(nx_) * size_t(ny_);
  auto lerp = [](float a, float b, float f) { return a + (b - a) * f; };
  const float y0 = lerp(lerp(d[0], d[1], fx), lerp(d[sy], d[sy + 1], fx), fy);
  const float y1 = lerp(lerp(d[sz], d[sz + 1], fx), lerp(d[sz + sy], d[sz + sy + 1], fx), fy);
  return lerp(y0, y1, fz);
}

PaddedGrid CpuVolume::grid() const {
  PaddedGrid g;
  for (int c = 0; c < components(); ++c) g.component[c] = data_[c].data();
  g.nx = nx_;
  g.ny = ny_;
  g.nz = nz_;
  return g;
}

}  // namespace fluoro::cpu
