#include "kernels/cpu/cpu_volume.hpp"

#include <tbb/parallel_for.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace fluoro::cpu {

CpuVolume::CpuVolume(const VolumeGeometry& g, const void* owner, const std::vector<const float*>& components,
                     bool is_signed)
    : DeviceVolume(g, int(components.size()), owner),
      nx_(g.size.x() + 2),
      ny_(g.size.y() + 2),
      nz_(g.size.z() + 2),
      is_signed_(is_signed) {
  for (size_t c = 0; c < components.size(); ++c) {
    words_[c].resize(size_t(nx_) * size_t(ny_) * size_t(nz_));
    set_component(int(c), components[c]);
  }
  build_occupancy();
}

void CpuVolume::build_occupancy() {
  bricks_x_ = (nx_ + kBrick - 1) / kBrick;
  bricks_y_ = (ny_ + kBrick - 1) / kBrick;
  bricks_z_ = (nz_ + kBrick - 1) / kBrick;
  occupancy_.assign(size_t(bricks_x_) * size_t(bricks_y_) * size_t(bricks_z_), 0);
  // A sample with lower corner (i, j, k) reads words (i, j..j+1, k..k+1); each word also holds
  // voxel i + 1. So a brick covers words x in [x0, x0 + kBrick), y and z one further.
  tbb::parallel_for(0, bricks_z_, [&](int bz) {
    for (int by = 0; by < bricks_y_; ++by)
      for (int bx = 0; bx < bricks_x_; ++bx) {
        bool any = false;
        for (int z = bz * kBrick; z <= std::min(bz * kBrick + kBrick, nz_ - 1) && !any; ++z)
          for (int y = by * kBrick; y <= std::min(by * kBrick + kBrick, ny_ - 1) && !any; ++y)
            for (int x = bx * kBrick; x < std::min(bx * kBrick + kBrick, nx_) && !any; ++x)
              for (int c = 0; c < components() && !any; ++c) any = words_[c][padded_index(x, y, z)] != 0;
        occupancy_[(size_t(bz) * size_t(bricks_y_) + size_t(by)) * size_t(bricks_x_) + size_t(bx)] = any;
      }
  });
  // Chebyshev distance (in bricks) of every empty brick to the nearest occupied one, capped: the
  // occupied set grown by one brick per round (a 3x3x3 max filter, separable) until the cap.
  constexpr int kMaxDistance = 32;
  const size_t n = occupancy_.size();
  std::vector<uint8_t> grown(n), tmp(n);
  std::vector<int32_t> distance(n, kMaxDistance);
  for (size_t i = 0; i < n; ++i) {
    grown[i] = occupancy_[i] != 0;
    if (grown[i]) distance[i] = 0;
  }
  const int dims[3] = {bricks_x_, bricks_y_, bricks_z_};
  const size_t stride[3] = {1, size_t(bricks_x_), size_t(bricks_x_) * size_t(bricks_y_)};
  for (int round = 1; round < kMaxDistance; ++round) {
    for (int axis = 0; axis < 3; ++axis) {
      tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          const int pos = int((i / stride[axis]) % size_t(dims[axis]));
          uint8_t v = grown[i];
          if (pos > 0) v |= grown[i - stride[axis]];
          if (pos + 1 < dims[axis]) v |= grown[i + stride[axis]];
          tmp[i] = v;
        }
      });
      std::swap(grown, tmp);
    }
    bool changed = false;
    for (size_t i = 0; i < n; ++i)
      if (grown[i] && distance[i] == kMaxDistance) {
        distance[i] = round;
        changed = true;
      }
    if (!changed) break;
  }
  occupancy_ = std::move(distance);
}

double CpuVolume::occupied_fraction() const {
  size_t n = 0;
  for (int32_t d : occupancy_) n += d == 0;
  return occupancy_.empty() ? 0.0 : double(n) / double(occupancy_.size());
}

void CpuVolume::set_component(int c, const float* src) {
  const bool is_signed = is_signed_;
  const auto& n = geometry().size;
  const size_t count = geometry().voxel_count();
  const float max_abs = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, count), 0.0f,
      [&](const tbb::blocked_range<size_t>& r, float m) {
        for (size_t i = r.begin(); i != r.end(); ++i) m = std::max(m, std::abs(src[i]));
        return m;
      },
      [](float a, float b) { return std::max(a, b); });
  const float levels = is_signed ? 32767.0f : 65535.0f;
  scale_[c] = max_abs > 0 ? max_abs / levels : 1.0f;
  const float inv = 1.0f / scale_[c];
  auto quantise = [&](float v) -> uint32_t {
    const float q = std::nearbyint(std::clamp(v * inv, is_signed ? -levels : 0.0f, levels));
    return is_signed ? uint32_t(uint16_t(int16_t(q))) : uint32_t(q);
  };
  std::vector<uint32_t>& dst = words_[c];
  tbb::parallel_for(0, nz_, [&](int kp) {
    const int k = std::clamp(kp - 1, 0, n.z() - 1);
    for (int jp = 0; jp < ny_; ++jp) {
      const int j = std::clamp(jp - 1, 0, n.y() - 1);
      const float* row = src + (size_t(k) * size_t(n.y()) + size_t(j)) * size_t(n.x());
      uint32_t* out = dst.data() + padded_index(0, jp, kp);
      // Padded x = 0 .. nx_-1 reads row[clamp(x - 1)]; each word also carries the next voxel.
      uint32_t next = quantise(row[0]);
      for (int xp = 0; xp < nx_; ++xp) {
        const uint32_t here = next;
        next = xp + 1 < nx_ ? quantise(row[std::clamp(xp, 0, n.x() - 1)]) : here;
        out[xp] = here | (next << 16);
      }
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
  const size_t b = padded_index(i, j, k), sy = size_t(nx_), sz = size_t(nx_) * size_t(ny_);
  auto lerp = [](float a, float e, float f) { return a + (e - a) * f; };
  auto row = [&](size_t w) { return lerp(value(c, w), value(c, w + 1), fx); };
  return lerp(lerp(row(b), row(b + sy), fy), lerp(row(b + sz), row(b + sz + sy), fy), fz);
}

PaddedGrid CpuVolume::grid() const {
  PaddedGrid g;
  for (int c = 0; c < components(); ++c) {
    g.component[c] = words_[c].data();
    g.scale[c] = scale_[c];
  }
  g.is_signed = is_signed_;
  g.occupancy = occupancy_.data();
  g.bricks_x = bricks_x_;
  g.bricks_y = bricks_y_;
  g.nx = nx_;
  g.ny = ny_;
  g.nz = nz_;
  return g;
}

}  // namespace fluoro::cpu
