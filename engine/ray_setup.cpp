#include "engine/ray_setup.hpp"

#include <algorithm>

namespace fluoro {

RaySetup make_ray_setup(const VolumeGeometry& g, const Pose& T_world_ct, const PinholeCamera& cam) {
  const Pose T_ct_world = T_world_ct.inverse();
  const Eigen::Matrix3d ct_to_index =
      g.spacing.cwiseInverse().asDiagonal() * g.direction.transpose();
  const Eigen::Matrix3d kinv = cam.K.inverse();
  const Eigen::Matrix3d cam_to_ct = T_ct_world.rotation() * cam.R.transpose();

  RaySetup s;
  s.source = g.physical_to_index(T_ct_world * cam.source());
  s.pixel_to_dir = ct_to_index * cam_to_ct * kinv;
  s.kinv = kinv;
  s.axis_u = cam_to_ct * kinv.col(0);
  s.axis_v = cam_to_ct * kinv.col(1);
  s.box_hi = g.size.cast<double>() - Eigen::Vector3d::Constant(0.5);
  return s;
}

PixelRay make_pixel_ray(const RaySetup& s, double u, double v, double step_mm) {
  const Eigen::Vector3d p(u, v, 1);
  PixelRay r;
  r.inv_len = 1.0 / (s.kinv * p).norm();
  r.dir = s.pixel_to_dir * p * r.inv_len;
  double t1;
  clip_ray_to_box<double>(s.source, r.dir, s.box_hi, r.t0, t1);
  r.n = sample_count<double>(r.t0, t1, step_mm);
  r.h = r.n ? (t1 - r.t0) / r.n : 0;
  return r;
}

void make_pixel_rays(const RaySetup& s, const double* u, const double* v, int count, double step_mm, PixelRay* out) {
  constexpr int kChunk = 16;  // enough rays in flight to overlap their divisions (a cpu packet holds 64)
  double t1[kChunk];
  for (int base = 0; base < count; base += kChunk) {
    const int n = std::min(kChunk, count - base);
    PixelRay* r = out + base;
    // Each pass is one step of make_pixel_ray for every pixel of the chunk, written as there.
    for (int i = 0; i < n; ++i) r[i].inv_len = 1.0 / (s.kinv * Eigen::Vector3d(u[base + i], v[base + i], 1)).norm();
    for (int i = 0; i < n; ++i) r[i].dir = s.pixel_to_dir * Eigen::Vector3d(u[base + i], v[base + i], 1) * r[i].inv_len;
    for (int i = 0; i < n; ++i) clip_ray_to_box<double>(s.source, r[i].dir, s.box_hi, r[i].t0, t1[i]);
    for (int i = 0; i < n; ++i) r[i].n = sample_count<double>(r[i].t0, t1[i], step_mm);
    for (int i = 0; i < n; ++i) r[i].h = r[i].n ? (t1[i] - r[i].t0) / r[i].n : 0;
  }
}

std::vector<uint32_t> tile_order(const std::vector<Eigen::Vector2f>& px) {
  std::vector<uint32_t> order(px.size());
  std::vector<uint64_t> key(px.size());
  for (size_t i = 0; i < px.size(); ++i) {
    const auto x = uint64_t(std::clamp(px[i].x(), 0.0f, 65535.0f)), y = uint64_t(std::clamp(px[i].y(), 0.0f, 65535.0f));
    key[i] = ((y >> 3) << 48) | ((x >> 3) << 32) | ((y & 7) << 16) | (x & 7);
    order[i] = uint32_t(i);
  }
  if (std::is_sorted(key.begin(), key.end())) return order;
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return key[a] < key[b]; });
  return order;
}

}  // namespace fluoro
