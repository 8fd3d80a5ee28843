#include "kernels/cpu/cpu_volume.hpp"

#include "engine/error.hpp"
#include "engine/float_scan.hpp"

#include <tbb/parallel_for.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <limits>
#include <new>
#include <stdexcept>

namespace fluoro::cpu {

namespace {

struct Range {
  float min = std::numeric_limits<float>::infinity(), max = -std::numeric_limits<float>::infinity();
  bool finite = true;
};

Range value_range(const float* v, size_t count) {
  return tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, count, 1 << 16), Range{},
      [&](const tbb::blocked_range<size_t>& r, Range acc) {
        if (!all_finite(v + r.begin(), r.size())) {
          acc.finite = false;
          return acc;
        }
        const FloatRange here = finite_range(v + r.begin(), r.size());
        acc.min = std::min(acc.min, here.min);
        acc.max = std::max(acc.max, here.max);
        return acc;
      },
      [](Range a, const Range& b) {
        a.min = std::min(a.min, b.min);
        a.max = std::max(a.max, b.max);
        a.finite = a.finite && b.finite;
        return a;
      });
}

}  // namespace

CpuVolume::CpuVolume(const VolumeGeometry& g, const void* owner, const std::vector<const float*>& components)
    : DeviceVolume(g, int(components.size()), owner),
      nx_(g.size.x() + 2),
      ny_(g.size.y() + 2),
      nz_(g.size.z() + 2),
      brick_shift_(brick_shift_for(g.spacing.minCoeff())) {
  if (components.size() != 1 && components.size() != 3)
    throw std::invalid_argument("cpu volume: 1 or 3 components, not " + std::to_string(components.size()));
  vector_ = components.size() == 3;
  // The ray marchers index voxels with signed 32-bit offsets.
  if (double(nx_) * double(ny_) * double(nz_) >= 2147483648.0)
    throw InputError("cpu.upload: volume of " + std::to_string(g.size.x()) + "x" + std::to_string(g.size.y()) + "x" +
                     std::to_string(g.size.z()) + " voxels exceeds the cpu backend's 2^31-voxel limit");
  std::vector<Range> ranges;
  for (const float* c : components) {
    ranges.push_back(value_range(c, g.voxel_count()));
    if (!ranges.back().finite) throw InputError("cpu.upload: non-finite voxel values");
    is_signed_ = is_signed_ || ranges.back().min < 0;
  }
  const size_t words = size_t(nx_) * size_t(ny_) * size_t(nz_);
  try {
    words_.resize(words);
  } catch (const std::bad_alloc&) {
    throw InputError("cpu.upload: volume of " + std::to_string(g.size.x()) + "x" + std::to_string(g.size.y()) + "x" +
                     std::to_string(g.size.z()) + " voxels needs " +
                     std::to_string(double(words * sizeof(uint64_t)) / double(1ull << 30)) +
                     " GiB (8 bytes per voxel), more than can be allocated");
  }
  for (size_t c = 0; c < components.size(); ++c)
    set_component(int(c), components[c], std::max(std::abs(ranges[c].min), std::abs(ranges[c].max)));
  build_occupancy();
}

namespace {

// The saved form's head (CpuVolume::save).
struct SavedHead {
  uint32_t is_signed, vector;
  float scale[3];
  int32_t bricks[3];
};
static_assert(sizeof(SavedHead) == 32);

size_t round_up8(size_t n) { return (n + 7) / 8 * 8; }

}  // namespace

std::vector<uint8_t> CpuVolume::save() const {
  const size_t voxels = words_.size();
  const size_t voxel_bytes = vector_ ? voxels * 8 : round_up8(voxels * 2);
  std::vector<uint8_t> out(sizeof(SavedHead) + voxel_bytes + occupancy_.size() * 4);
  SavedHead head{uint32_t(is_signed_), uint32_t(vector_), {scale_[0], scale_[1], scale_[2]}, {bricks_x_, bricks_y_, bricks_z_}};
  std::memcpy(out.data(), &head, sizeof head);
  uint8_t* v = out.data() + sizeof head;
  if (vector_) {
    std::memcpy(v, words_.data(), voxels * 8);
  } else {
    // Each scalar word's low half-word is its own voxel's quantum; the rest repeats neighbours.
    uint16_t* q = reinterpret_cast<uint16_t*>(v);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, voxels, 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t n = r.begin(); n != r.end(); ++n) q[n] = uint16_t(words_[n] & 0xFFFFu);
    });
  }
  std::memcpy(v + voxel_bytes, occupancy_.data(), occupancy_.size() * 4);
  return out;
}

CpuVolume::CpuVolume(const VolumeGeometry& g, const void* owner, int components, std::span<const uint8_t> bytes,
                     const std::string& what)
    : DeviceVolume(g, components, owner),
      nx_(g.size.x() + 2),
      ny_(g.size.y() + 2),
      nz_(g.size.z() + 2),
      brick_shift_(brick_shift_for(g.spacing.minCoeff())) {
  vector_ = components == 3;
  count_bricks();
  const size_t voxels = size_t(nx_) * size_t(ny_) * size_t(nz_);
  const size_t bricks = size_t(bricks_x_) * size_t(bricks_y_) * size_t(bricks_z_);
  const size_t voxel_bytes = vector_ ? voxels * 8 : round_up8(voxels * 2);
  if (bytes.size() != sizeof(SavedHead) + voxel_bytes + bricks * 4)
    throw InputError(what + ": " + std::to_string(bytes.size()) + " bytes do not hold a cpu volume of " +
                     std::to_string(g.size.x()) + "x" + std::to_string(g.size.y()) + "x" + std::to_string(g.size.z()) +
                     " voxels");
  SavedHead head;
  std::memcpy(&head, bytes.data(), sizeof head);
  if (head.vector != uint32_t(vector_) || head.is_signed > 1 || head.bricks[0] != bricks_x_ || head.bricks[1] != bricks_y_ ||
      head.bricks[2] != bricks_z_)
    throw InputError(what + ": the cpu volume's head disagrees with its geometry");
  for (int c = 0; c < 3; ++c) {
    if (!(std::isfinite(head.scale[c]) && head.scale[c] > 0)) throw InputError(what + ": invalid quantum scale");
    scale_[c] = head.scale[c];
  }
  is_signed_ = head.is_signed != 0;
  const uint8_t* v = bytes.data() + sizeof head;
  words_.resize(voxels);
  if (vector_) {
    // In pieces over the cores: the copy's cost is mostly first touches of the new pages.
    constexpr size_t kPiece = size_t(1) << 19;  // words: 4 MiB, two huge pages
    tbb::parallel_for(tbb::blocked_range<size_t>(0, voxels, kPiece), [&](const tbb::blocked_range<size_t>& r) {
      std::memcpy(words_.data() + r.begin(), v + 8 * r.begin(), 8 * r.size());
    });
  } else {
    // Rebuild each word's quad exactly as set_component packs it: (x, y), (x + 1, y), (x, y + 1),
    // (x + 1, y + 1), the last padded column and row repeating themselves.
    tbb::parallel_for(0, nz_, [&](int kp) {
      auto q = [&](int x, int y) {
        uint16_t value;
        std::memcpy(&value, v + 2 * padded_index(x, y, kp), 2);
        return uint64_t(value);
      };
      for (int jp = 0; jp < ny_; ++jp) {
        const int j1 = std::min(jp + 1, ny_ - 1);
        uint64_t* out = words_.data() + padded_index(0, jp, kp);
        for (int xp = 0; xp < nx_; ++xp) {
          const int x1 = std::min(xp + 1, nx_ - 1);
          out[xp] = q(xp, jp) | q(x1, jp) << 16 | q(xp, j1) << 32 | q(x1, j1) << 48;
        }
      }
    });
  }
  occupancy_.resize(bricks);
  std::memcpy(occupancy_.data(), v + voxel_bytes, bricks * 4);
  find_occupied_box();
}

CpuVolume::CpuVolume(const CpuVolume& source, const void* owner, double relative_tolerance)
    : DeviceVolume(source.geometry(), source.components(), owner),
      nx_(source.nx_),
      ny_(source.ny_),
      nz_(source.nz_),
      brick_shift_(source.brick_shift_),
      is_signed_(source.is_signed_),
      vector_(source.vector_),
      words_(source.words_) {
  if (!vector_) throw std::invalid_argument("cpu volume: only a gradient field can be floored");
  std::copy(std::begin(source.scale_), std::end(source.scale_), std::begin(scale_));
  // Squared magnitudes in double, as the reference backend compares them; the padding repeats
  // edge voxels, so it is floored exactly as they are.
  auto squared = [&](uint64_t w) {
    double s = 0;
    for (int c = 0; c < 3; ++c) {
      const uint32_t half = uint32_t((w >> (16 * c)) & 0xFFFFu);
      const double v = double(scale_[c]) * (is_signed_ ? double(int16_t(uint16_t(half))) : double(half));
      s += v * v;
    }
    return s;
  };
  const double max_squared = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, words_.size(), 1 << 16), 0.0,
      [&](const tbb::blocked_range<size_t>& r, double m) {
        for (size_t n = r.begin(); n != r.end(); ++n) m = std::max(m, squared(words_[n]));
        return m;
      },
      [](double a, double b) { return std::max(a, b); });
  const double floor_squared = max_squared * relative_tolerance * relative_tolerance;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, words_.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t n = r.begin(); n != r.end(); ++n)
      if (squared(words_[n]) < floor_squared) words_[n] = 0;
  });
  build_occupancy();
}

void CpuVolume::count_bricks() {
  const int brick = 1 << brick_shift_;
  bricks_x_ = (nx_ + brick - 1) / brick;
  bricks_y_ = (ny_ + brick - 1) / brick;
  bricks_z_ = (nz_ + brick - 1) / brick;
}

void CpuVolume::build_occupancy() {
  count_bricks();
  const int brick = 1 << brick_shift_;
  occupancy_.assign(size_t(bricks_x_) * size_t(bricks_y_) * size_t(bricks_z_), 0);
  // A sample with lower corner (i, j, k) reads voxels i..i+1, j..j+1, k..k+1. Scalar words also
  // hold voxels i + 1 and j + 1, so a brick covers words x and y in [x0, x0 + brick) and z one
  // further; vector words hold their own voxel only, so x and y reach one further too.
  const int reach = vector_ ? 1 : 0;
  // Streamed in memory order so that it vectorises: the OR of a brick's slices, word by word,
  // into one slice, then the OR of each brick's rows and columns within it.
  tbb::parallel_for(0, bricks_z_, [&](int bz) {
    const size_t slice = size_t(nx_) * size_t(ny_);
    std::vector<uint64_t> merged(words_.begin() + std::ptrdiff_t(size_t(bz) * brick * slice),
                                 words_.begin() + std::ptrdiff_t((size_t(bz) * brick + 1) * slice));
    for (int z = bz * brick + 1; z <= std::min(bz * brick + brick, nz_ - 1); ++z) {
      const uint64_t* w = words_.data() + size_t(z) * slice;
      for (size_t n = 0; n < slice; ++n) merged[n] |= w[n];
    }
    for (int by = 0; by < bricks_y_; ++by)
      for (int bx = 0; bx < bricks_x_; ++bx) {
        uint64_t any = 0;
        for (int y = by * brick; y < std::min(by * brick + brick + reach, ny_); ++y) {
          const uint64_t* row = merged.data() + size_t(y) * size_t(nx_);
          for (int x = bx * brick; x < std::min(bx * brick + brick + reach, nx_); ++x) any |= row[x];
        }
        occupancy_[(size_t(bz) * size_t(bricks_y_) + size_t(by)) * size_t(bricks_x_) + size_t(bx)] = any != 0;
      }
  });
  // Chebyshev distance (in bricks, capped) of every empty brick to the nearest occupied one: a
  // two-pass chamfer sweep over the 26-neighbourhood with unit weights, exact for this metric.
  // Within a sweep, the 12 neighbours in the previous row and slice are combined a whole row at a
  // time (vectorised); only the neighbour along the row itself is a sequential scan.
  constexpr int32_t kMaxDistance = 32;
  for (int32_t& d : occupancy_) d = d ? 0 : kMaxDistance;
  const int nx = bricks_x_, ny = bricks_y_, nz = bricks_z_;
  std::vector<int32_t> best(size_t(nx) + 2), spread(size_t(nx) + 2);
  auto row = [&](int y, int z) { return occupancy_.data() + (size_t(z) * size_t(ny) + size_t(y)) * size_t(nx); };
  auto sweep = [&](int sign) {
    const int z0 = sign > 0 ? 0 : nz - 1, y0 = sign > 0 ? 0 : ny - 1;
    for (int z = z0; z >= 0 && z < nz; z += sign)
      for (int y = y0; y >= 0 && y < ny; y += sign) {
        // best[x + 1] = min over the already visited rows (y - sign in this slice; y - sign,
        // y, y + sign in the previous slice) at x - 1, x, x + 1; +1 for the step.
        std::fill(best.begin(), best.end(), kMaxDistance);
        auto take = [&](const int32_t* r) {
          for (int x = 0; x < nx; ++x) best[size_t(x) + 1] = std::min(best[size_t(x) + 1], r[x]);
        };
        const int yp = y - sign, zp = z - sign;
        if (yp >= 0 && yp < ny) take(row(yp, z));
        if (zp >= 0 && zp < nz)
          for (int dy = -1; dy <= 1; ++dy)
            if (y + dy >= 0 && y + dy < ny) take(row(y + dy, zp));
        int32_t* d = row(y, z);
        // Spread along x (the x +- 1 neighbours of those rows), then the scan along the row.
        for (int x = 0; x < nx; ++x)
          spread[size_t(x) + 1] = std::min({best[size_t(x)], best[size_t(x) + 1], best[size_t(x) + 2]});
        for (int x = 0; x < nx; ++x) d[x] = std::min(d[x], spread[size_t(x) + 1] + 1);
        if (sign > 0)
          for (int x = 1; x < nx; ++x) d[x] = std::min(d[x], d[x - 1] + 1);
        else
          for (int x = nx - 2; x >= 0; --x) d[x] = std::min(d[x], d[x + 1] + 1);
      }
  };
  sweep(+1);
  sweep(-1);
  find_occupied_box();
}

void CpuVolume::find_occupied_box() {
  constexpr float kUnbounded = 1e30f;
  int lo[3] = {bricks_x_, bricks_y_, bricks_z_}, hi[3] = {-1, -1, -1};
  for (int z = 0; z < bricks_z_; ++z)
    for (int y = 0; y < bricks_y_; ++y)
      for (int x = 0; x < bricks_x_; ++x)
        if (occupancy_[(size_t(z) * size_t(bricks_y_) + size_t(y)) * size_t(bricks_x_) + size_t(x)] == 0) {
          const int b[3] = {x, y, z};
          for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], b[a]);
            hi[a] = std::max(hi[a], b[a]);
          }
        }
  // Lower corners in bricks lo .. hi: positions from the first brick's lower face to the last
  // one's upper face (nothing occupied: lo > hi, an empty box). The marchers clamp positions into
  // the padded volume (lower corners 0 to n - 2), so a box that reaches a face reaches past it.
  const int last_corner[3] = {nx_ - 2, ny_ - 2, nz_ - 2};
  for (int a = 0; a < 3; ++a) {
    occupied_lo_[a] = lo[a] == 0 ? -kUnbounded : float(lo[a] << brick_shift_);
    occupied_hi_[a] = lo[a] <= hi[a] && ((hi[a] + 1) << brick_shift_) > last_corner[a] ? kUnbounded
                                                                                     : float((hi[a] + 1) << brick_shift_);
  }
}

double CpuVolume::occupied_fraction() const {
  size_t n = 0;
  for (int32_t d : occupancy_) n += d == 0;
  return occupancy_.empty() ? 0.0 : double(n) / double(occupancy_.size());
}

void CpuVolume::set_component(int c, const float* src, float max_abs) {
  const auto& n = geometry().size;
  const bool is_signed = is_signed_;
  const float levels = is_signed ? 32767.0f : 65535.0f;
  // A scale below the smallest normal float would make its inverse infinite and 0 * inf a NaN
  // quantum (volumes that small hold nothing physical, but the Python bindings upload anything).
  scale_[c] = max_abs > 0 ? std::max(max_abs / levels, std::numeric_limits<float>::min()) : 1.0f;
  const float inv = 1.0f / scale_[c];
  auto quantise = [&](float v) -> uint32_t {
    const float x = std::clamp(v * inv, is_signed ? -levels : 0.0f, levels);
    const int q = int(x + (x >= 0 ? 0.5f : -0.5f));  // round half away from zero, inline
    return uint32_t(q) & 0xFFFFu;  // two's complement halves for negative values
  };
  uint64_t* const dst = words_.data();
  if (vector_) {
    // Component c's half-word of each voxel's word (the others are set by their own calls;
    // component 0 comes first and clears the rest, as the words start unwritten).
    const int shift = 16 * c;
    const uint64_t keep = c == 0 ? 0 : ~uint64_t(0);
    tbb::parallel_for(0, nz_, [&](int kp) {
      const int k = std::clamp(kp - 1, 0, n.z() - 1);
      for (int jp = 0; jp < ny_; ++jp) {
        const int j = std::clamp(jp - 1, 0, n.y() - 1);
        const float* row = src + (size_t(k) * size_t(n.y()) + size_t(j)) * size_t(n.x());
        uint64_t* out = dst + padded_index(0, jp, kp);
        for (int xp = 0; xp < nx_; ++xp)
          out[xp] = (out[xp] & keep) | uint64_t(quantise(row[std::clamp(xp - 1, 0, n.x() - 1)])) << shift;
      }
    });
    return;
  }
  tbb::parallel_for(0, nz_, [&](int kp) {
    const int k = std::clamp(kp - 1, 0, n.z() - 1);
    // The quanta of padded rows y and y + 1 (the last row repeats: it is padding), each with one
    // more entry repeating its last, so that word x is q[x], q[x + 1] of both rows. Quantised a row
    // at a time and packed in separate loops, both of which vectorise.
    const size_t width = size_t(nx_) + 1;
    std::vector<uint16_t> here(width), below(width);
    auto quantise_row = [&](int jp, std::vector<uint16_t>& q) {
      const int j = std::clamp(jp - 1, 0, n.y() - 1);
      const float* row = src + (size_t(k) * size_t(n.y()) + size_t(j)) * size_t(n.x());
      for (int i = 0; i < n.x(); ++i) q[size_t(i) + 1] = uint16_t(quantise(row[i]));
      q[0] = q[1];                                       // padded x = 0 repeats voxel 0
      q[size_t(nx_) - 1] = q[size_t(nx_) - 2];           // padded x = nx + 1 repeats voxel nx - 1
      q[size_t(nx_)] = q[size_t(nx_) - 1];               // the last word's x + 1 repeats itself
    };
    quantise_row(0, below);
    for (int jp = 0; jp < ny_; ++jp) {
      here.swap(below);
      if (jp + 1 < ny_) quantise_row(jp + 1, below);
      else below = here;
      uint64_t* out = dst + padded_index(0, jp, kp);
      for (int xp = 0; xp < nx_; ++xp)
        out[xp] = uint64_t(here[size_t(xp)]) | uint64_t(here[size_t(xp) + 1]) << 16 |
                  uint64_t(below[size_t(xp)]) << 32 | uint64_t(below[size_t(xp) + 1]) << 48;
    }
  });
}

float CpuVolume::sample(int c, float x, float y, float z) const {
  // Into padded coordinates, clamped to the padded box like the SIMD kernel.
  x = std::clamp(x + 1.0f, 0.0f, float(nx_) - 1.001f);
  y = std::clamp(y + 1.0f, 0.0f, float(ny_) - 1.001f);
  z = std::clamp(z + 1.0f, 0.0f, float(nz_) - 1.001f);
  const int i = std::min(int(x), nx_ - 2), j = std::min(int(y), ny_ - 2), k = std::min(int(z), nz_ - 2);
  const float fx = x - float(i), fy = y - float(j), fz = z - float(k);
  const size_t b = padded_index(i, j, k), sy = size_t(nx_), sz = size_t(nx_) * size_t(ny_);
  auto lerp = [](float a, float e, float f) { return a + (e - a) * f; };
  auto row = [&](size_t w) { return lerp(value(c, w), value(c, w + 1), fx); };
  return lerp(lerp(row(b), row(b + sy), fy), lerp(row(b + sz), row(b + sz + sy), fy), fz);
}

PaddedGrid CpuVolume::grid() const {
  PaddedGrid g;
  g.words = words_.data();
  g.vector_voxels = vector_;
  for (int c = 0; c < components(); ++c) g.scale[c] = scale_[c];
  g.is_signed = is_signed_;
  g.occupancy = occupancy_.data();
  g.bricks_x = bricks_x_;
  g.bricks_y = bricks_y_;
  g.brick_shift = brick_shift_;
  g.nx = nx_;
  g.ny = ny_;
  g.nz = nz_;
  std::copy(std::begin(occupied_lo_), std::end(occupied_lo_), std::begin(g.occupied_lo));
  std::copy(std::begin(occupied_hi_), std::end(occupied_hi_), std::begin(g.occupied_hi));
  return g;
}

}  // namespace fluoro::cpu
