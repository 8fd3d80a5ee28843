#pragma once
// Per (pose, view) ray geometry in a volume's continuous index space, computed once on the host in
// double precision and shared by every backend, so that all of them march the same rays.
//
// For pixel p = (u, v, 1), with K^-1 p of length |d|, the world ray is C + t * R^T K^-1 p / |d|,
// t in mm. In index space it is source + t * (pixel_to_dir * p) / |kinv * p|.
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "engine/camera.hpp"
#include "engine/pose.hpp"
#include "engine/volume.hpp"

namespace fluoro {

struct RaySetup {
  Eigen::Vector3d source;        // the X-ray source, in continuous index coordinates
  Eigen::Matrix3d pixel_to_dir;  // S^-1 D^T R_ct_world R^T K^-1
  Eigen::Matrix3d kinv;          // K^-1, whose product with p has length |d|
  // CT-frame physical vectors R_ct_world R^T K^-1 e_u and R_ct_world R^T K^-1 e_v: the motion of a
  // point at unit camera depth when the pixel moves by one column or one row.
  Eigen::Vector3d axis_u, axis_v;
  Eigen::Vector3d box_hi;        // size - 0.5; the box is [-0.5, box_hi]
};

RaySetup make_ray_setup(const VolumeGeometry& g, const Pose& T_world_ct, const PinholeCamera& cam);

// The ray through one pixel, clipped and divided into samples: sample k is at
// s.source + (t0 + (k + 0.5) h) * dir (index space), t in mm from the source. n = 0: a miss.
struct PixelRay {
  Eigen::Vector3d dir;  // index-space direction per mm of travel
  double inv_len;       // 1 / |K^-1 p|
  double t0, h;
  int n;
};
PixelRay make_pixel_ray(const RaySetup& s, double u, double v, double step_mm);

// make_pixel_ray for `count` pixels (u[i], v[i]) into out[i]: the same operations in the same
// order, so the same rays bit for bit (tests/ray_setup_test.cpp), but in passes over the pixels, so
// that the divisions and square roots of different rays overlap instead of each ray's chain of
// them waiting on the one before (a ray's setup was a fifth of a bone DRR's time on the cpu
// backend: docs/benchmarks.md, "Where a bone DRR's time goes").
void make_pixel_rays(const RaySetup& s, const double* u, const double* v, int count, double step_mm, PixelRay* out);

// Indices of the pixels sorted by 8 x 8 tiles (row-major tiles, row-major within a tile): rays
// marched in this order read nearly the same voxels one after another (every fast backend).
// Pixels already in that order (see EdgePixels' tile_ordered) cost one pass, not a sort.
std::vector<uint32_t> tile_order(const std::vector<Eigen::Vector2f>& pixels);

// The parameter interval [t0, t1] (mm from the source, t0 >= 0) where the ray with index-space
// direction `dir` (per mm) lies inside the box; empty (t1 <= t0) if it misses.
template <class T, class V>
inline void clip_ray_to_box(const V& origin, const V& dir, const V& box_hi, T& t0, T& t1) {
  t0 = T(0);
  t1 = T(1e30);
  for (int a = 0; a < 3; ++a) {
    const T lo = T(-0.5), hi = box_hi[a];
    if (!std::isfinite(dir[a]) || !std::isfinite(origin[a])) {  // a NaN pixel or direction: no ray
      t1 = T(-1);
      continue;
    }
    if (dir[a] == T(0)) {
      if (origin[a] < lo || origin[a] > hi) t1 = T(-1);
      continue;
    }
    const T inv = T(1) / dir[a];
    T ta = (lo - origin[a]) * inv, tb = (hi - origin[a]) * inv;
    if (ta > tb) std::swap(ta, tb);
    t0 = ta > t0 ? ta : t0;
    t1 = tb < t1 ? tb : t1;
  }
}

// Samples along a clipped chord: n midpoints at t0 + (k + 0.5) h with h = (t1 - t0) / n and
// n = ceil((t1 - t0) / step), so h * n is the exact chord length (a uniform volume integrates
// exactly).
template <class T>
inline int sample_count(T t0, T t1, T step) {
  if (!(t1 > t0)) return 0;
  const T n = std::ceil((t1 - t0) / step);
  return n < T(1) ? 1 : int(n);
}

}  // namespace fluoro
