// The cpu backend: float kernels, oneTBB across cores, Highway SIMD within a core (ray_march.cpp).
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <numbers>
#include <type_traits>

#include "kernels/cpu/cpu_backend.hpp"
#include "engine/error.hpp"
#include "engine/ray_setup.hpp"
#include "kernels/cpu/cpu_volume.hpp"
#include "kernels/cpu/gradient_field.hpp"
#include "kernels/cpu/ray_march.hpp"

namespace fluoro::cpu {
namespace {

// Fills a packet with the rays through `count` pixels; returns 1/|K^-1 p| per ray in inv_len.
template <class PixelAt>
void fill_packet(const RaySetup& s, int count, double step_mm, PixelAt&& pixel_at, RayPacket& p,
                 float* inv_len) {
  for (int i = 0; i < kPacketRays; ++i) {
    p.n[i] = 0;
    p.t0[i] = p.h[i] = 0;
    p.entry_x[i] = p.entry_y[i] = p.entry_z[i] = 0;
    p.step_x[i] = p.step_y[i] = p.step_z[i] = 0;
    inv_len[i] = 0;
  }
  double u[kPacketRays] = {}, v[kPacketRays] = {};
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector2d px = pixel_at(i);
    u[i] = px.x();
    v[i] = px.y();
  }
  PixelRay rays[kPacketRays];
  make_pixel_rays(s, u, v, count, step_mm, rays);
  for (int i = 0; i < count; ++i) {
    const PixelRay& r = rays[i];
    if (r.n == 0) continue;
    const Eigen::Vector3d& dir = r.dir;
    const double h = r.h;
    // +1: voxel (0, 0, 0) is padded index (1, 1, 1).
    const Eigen::Vector3d entry = s.source + r.t0 * dir + Eigen::Vector3d::Ones();
    p.entry_x[i] = float(entry.x());
    p.entry_y[i] = float(entry.y());
    p.entry_z[i] = float(entry.z());
    p.step_x[i] = float(dir.x() * h);
    p.step_y[i] = float(dir.y() * h);
    p.step_z[i] = float(dir.z() * h);
    p.t0[i] = float(r.t0);
    p.h[i] = float(h);
    p.n[i] = r.n;
    inv_len[i] = float(r.inv_len);
  }
}

// The pixels (u0..u1, v0..v1; image coordinates, inclusive) outside which a ray meets no occupied
// brick of the grid, so that its DRR pixel is exactly 0 and needs neither set-up nor marching:
// the bounding rectangle of the projected corners of the occupied box (PaddedGrid::occupied_lo,
// _hi, clipped to the volume's box, a voxel to spare), a pixel to spare. Every pixel (an unbounded
// rectangle) when a corner is not in front of the source.
struct PixelBounds {
  double u0 = -1e300, u1 = 1e300, v0 = -1e300, v1 = 1e300;
};
PixelBounds occupied_pixel_bounds(const PaddedGrid& g, const RaySetup& s) {
  PixelBounds b;
  Eigen::Vector3d lo, hi;
  for (int a = 0; a < 3; ++a) {
    // Padded positions to index coordinates (-1), within the volume's box [-0.5, box_hi].
    lo[a] = std::max(double(g.occupied_lo[a]) - 1.0, -0.5) - 1.0;
    hi[a] = std::min(double(g.occupied_hi[a]) - 1.0, s.box_hi[a]) + 1.0;
    if (!(lo[a] < hi[a])) return {0, -1, 0, -1};  // nothing occupied: no pixel
  }
  const Eigen::Matrix3d to_pixel = s.pixel_to_dir.inverse();
  double u0 = 1e300, u1 = -1e300, v0 = 1e300, v1 = -1e300;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner(c & 1 ? hi.x() : lo.x(), c & 2 ? hi.y() : lo.y(), c & 4 ? hi.z() : lo.z());
    const Eigen::Vector3d p = to_pixel * (corner - s.source);  // (u, v, 1) times the depth
    if (!(p.z() > 1e-9 * p.norm())) return b;  // a corner beside or behind the source
    u0 = std::min(u0, p.x() / p.z());
    u1 = std::max(u1, p.x() / p.z());
    v0 = std::min(v0, p.y() / p.z());
    v1 = std::max(v1, p.y() / p.z());
  }
  if (!std::isfinite(u0 + u1 + v0 + v1)) return b;
  return {u0 - 1.0, u1 + 1.0, v0 - 1.0, v1 + 1.0};
}

// march_weighted_gradients with the packet's rays grouped by where they enter the occupied box: a
// SIMD group marches from its first ray's entry to its last one's exit, and the rays of a packet
// of a sparse subset of edge pixels (the first fine stages'), which spans many tiles, enter the
// bone's box at depths that differ by more than their length inside it (the femur demo's first two
// fine stages 1.5x and 1.7x faster; docs/benchmarks.md). The outputs are in the packet's order, and
// each ray's the same bit for bit (a ray's sum does not depend on its group: the steps a group adds
// or skips are zero for it).
void march_by_entry(const PaddedGrid& grid, const RayPacket& packet, int count, bool nearest, float* gx, float* gy,
                    float* gz) {
  float key[kPacketRays], leave[kPacketRays];  // the steps at which each ray enters and leaves the box
  for (int i = 0; i < count; ++i) {
    float t_in = -1e30f, t_out = 1e30f;
    const float e[3] = {packet.entry_x[i], packet.entry_y[i], packet.entry_z[i]},
                st[3] = {packet.step_x[i], packet.step_y[i], packet.step_z[i]};
    for (int a = 0; a < 3; ++a)
      if (std::abs(st[a]) >= 1e-6f) {
        const float lo = (grid.occupied_lo[a] - e[a]) / st[a], hi = (grid.occupied_hi[a] - e[a]) / st[a];
        t_in = std::max(t_in, std::min(lo, hi));
        t_out = std::min(t_out, std::max(lo, hi));
      }
    const bool enters = packet.n[i] > 0 && t_in <= t_out;
    key[i] = enters ? std::max(t_in, 0.0f) : 1e30f;
    leave[i] = enters ? std::min(t_out, float(packet.n[i])) : -1e30f;
  }
  constexpr int kGroup = 16;  // the widest SIMD group (AVX-512)
  // The sum over SIMD groups of last exit - first entry, the rays in the order `at` (null: the packet's).
  auto total_span = [&](const int* at) {
    float total = 0;
    for (int g0 = 0; g0 < count; g0 += kGroup) {
      float first = 1e30f, last = -1e30f;
      for (int i = g0; i < std::min(count, g0 + kGroup); ++i) {
        const int r = at ? at[i] : i;
        first = std::min(first, key[r]);
        last = std::max(last, leave[r]);
      }
      if (last > first) total += last - first;
    }
    return total;
  };
  // Sorted by entry, ties in the packet's order.
  int perm[kPacketRays];
  std::iota(perm, perm + count, 0);
  std::stable_sort(perm, perm + count, [&](int a, int b) { return key[a] < key[b]; });
  // Regrouped only where that cuts the groups' steps by a quarter: a packet of neighbouring pixels
  // along a contour gains little, and its rays read the same voxels one after another.
  if (!(total_span(perm) < 0.75f * total_span(nullptr))) {
    march_weighted_gradients(grid, packet, count, nearest, gx, gy, gz);
    return;
  }
  RayPacket sorted{};
  for (int j = 0; j < count; ++j) {
    const int i = perm[j];
    sorted.entry_x[j] = packet.entry_x[i];
    sorted.entry_y[j] = packet.entry_y[i];
    sorted.entry_z[j] = packet.entry_z[i];
    sorted.step_x[j] = packet.step_x[i];
    sorted.step_y[j] = packet.step_y[i];
    sorted.step_z[j] = packet.step_z[i];
    sorted.t0[j] = packet.t0[i];
    sorted.h[j] = packet.h[i];
    sorted.n[j] = packet.n[i];
  }
  alignas(64) float sx[kPacketRays], sy[kPacketRays], sz[kPacketRays];
  march_weighted_gradients(grid, sorted, count, nearest, sx, sy, sz);
  for (int j = 0; j < count; ++j) {
    gx[perm[j]] = sx[j];
    gy[perm[j]] = sy[j];
    gz[perm[j]] = sz[j];
  }
}

class CpuBackend final : public Backend {
 public:
  std::string_view name() const override { return "cpu"; }
  bool supports(Op) const override { return true; }

  std::shared_ptr<const DeviceVolume> upload_impl(const Volume& mu) override {
    return std::make_shared<CpuVolume>(mu.geometry, this, std::vector<const float*>{mu.voxels.data()});
  }

  std::shared_ptr<const DeviceVolume> upload_impl(const VectorField& f) override {
    std::vector<float, DefaultInitAllocator<float>> c[3];  // written in full below
    for (int k = 0; k < 3; ++k) {
      c[k].resize(f.vectors.size());
      for (size_t n = 0; n < f.vectors.size(); ++n) c[k][n] = f.vectors[n][size_t(k)];
    }
    return std::make_shared<CpuVolume>(f.geometry, this, std::vector<const float*>{c[0].data(), c[1].data(), c[2].data()});
  }

  bool can_save_volumes() const override { return true; }
  std::vector<uint8_t> save_volume_impl(const DeviceVolume& v) override {
    return static_cast<const CpuVolume&>(v).save();
  }
  std::shared_ptr<const DeviceVolume> load_volume_impl(const VolumeGeometry& g, int components,
                                                       std::span<const uint8_t> bytes, const std::string& what) override {
    return std::make_shared<CpuVolume>(g, this, components, bytes, what);
  }

  VectorField download_gradient_impl(const DeviceVolume& handle) override {
    const auto& v = static_cast<const CpuVolume&>(handle);
    const VolumeGeometry& g = v.geometry();
    VectorField f{g, VectorBuffer(g.voxel_count())};
    for (int k = 0; k < g.size.z(); ++k)
      for (int j = 0; j < g.size.y(); ++j)
        for (int i = 0; i < g.size.x(); ++i)
          f.vectors[g.linear_index(i, j, k)] = {v.at(0, i, j, k), v.at(1, i, j, k), v.at(2, i, j, k)};
    return f;
  }

  std::shared_ptr<const DeviceVolume> gradient_field_impl(const DeviceVolume& handle,
                                                     const GradientFieldParams& params) override {
    return compute_gradient_field(static_cast<const CpuVolume&>(handle), params, this);
  }

  std::shared_ptr<const DeviceVolume> floor_gradient_impl(const DeviceVolume& handle,
                                                          const GradientFloorParams& params) override {
    return std::make_shared<CpuVolume>(static_cast<const CpuVolume&>(handle), this, params.relative_tolerance);
  }

  std::vector<Image> drr_impl(const DeviceVolume& handle, std::span<const Pose> poses,
                         std::span<const PinholeCamera> views, const DrrParams& params) override {
    const auto& mu = static_cast<const CpuVolume&>(handle);
    const PaddedGrid grid = mu.grid();
    const size_t n_images = poses.size() * views.size();
    std::vector<Image> out(n_images);
    std::vector<RaySetup> setups(n_images);
    std::vector<PixelWindow> windows(n_images);
    for (size_t p = 0; p < poses.size(); ++p)
      for (size_t v = 0; v < views.size(); ++v) {
        const size_t i = p * views.size() + v;
        windows[i] = resolve_window(params.window, views[v]);
        setups[i] = make_ray_setup(mu.geometry(), poses[p], views[v]);
        out[i] = Image(windows[i].width, windows[i].height);
      }
    // Work items: one row segment of kPacketRays pixels of one image.
    struct Item { uint32_t image; int y, x; };
    std::vector<Item> items;
    for (size_t i = 0; i < n_images; ++i)
      for (int y = 0; y < windows[i].height; ++y)
        for (int x = 0; x < windows[i].width; x += kPacketRays) items.push_back({uint32_t(i), y, x});
    // Pixels whose rays miss every occupied brick stay 0 (the images start at 0).
    std::vector<PixelBounds> bounds(n_images);
    if (grid.occupancy)  // the box is the brick map's (without one: every pixel)
      for (size_t i = 0; i < n_images; ++i) bounds[i] = occupied_pixel_bounds(grid, setups[i]);
    tbb::parallel_for(size_t(0), items.size(), [&](size_t w) {
      const Item& it = items[w];
      const PixelWindow& win = windows[it.image];
      const PixelBounds& b = bounds[it.image];
      const double v = win.y0 + it.y;
      if (v < b.v0 || v > b.v1) return;
      // The segment's pixels x0 .. x1 - 1 (window columns) within the bounds.
      const int x0 = std::max(it.x, int(std::clamp(std::ceil(b.u0 - win.x0), -1.0, double(win.width)))),
                x1 = std::min(it.x + kPacketRays, std::min(win.width, int(std::clamp(std::floor(b.u1 - win.x0), -1.0, double(win.width))) + 1));
      const int count = x1 - x0;
      if (count <= 0) return;
      RayPacket packet;
      alignas(64) float inv_len[kPacketRays], sums[kPacketRays];
      fill_packet(setups[it.image], count, params.step_mm,
                  [&](int i) { return Eigen::Vector2d(win.x0 + x0 + i, v); }, packet, inv_len);
      march_line_integrals(grid, packet, count, sums);
      float* row = out[it.image].pixels.data() + size_t(it.y) * size_t(win.width) + size_t(x0);
      std::copy(sums, sums + count, row);
    });
    return out;
  }

  std::vector<std::vector<Eigen::Vector2f>> gradient_projection_impl(
      const DeviceVolume& handle, std::span<const Pose> poses, std::span<const PinholeCamera> views,
      std::span<const std::vector<Eigen::Vector2f>> pixels, const ProjectionParams& params) override {
    std::vector<std::vector<Eigen::Vector2f>> out(poses.size() * views.size());
    for (size_t p = 0; p < poses.size(); ++p)
      for (size_t v = 0; v < views.size(); ++v) out[p * views.size() + v].resize(pixels[v].size());
    for_each_projection(static_cast<const CpuVolume&>(handle), poses, views, pixels, params,
                        [&](size_t image, const uint32_t* index, int count, const Eigen::Vector2f* g) {
                          for (int i = 0; i < count; ++i) out[image][index[i]] = g[i];
                        });
    return out;
  }

  std::vector<double> gpr_score_impl(const DeviceVolume& handle, std::span<const Pose> poses,
                                std::span<const PinholeCamera> views,
                                std::span<const EdgePixels> edges, const GprParams& params) override {
    std::vector<std::vector<Eigen::Vector2f>> pixels(views.size());
    for (size_t v = 0; v < views.size(); ++v) pixels[v] = edges[v].pixels;
    const float cos_max = float(std::cos(params.max_angle_deg * std::numbers::pi / 180.0));
    // Partial sums per packet, then added per pose in a fixed order: the same result every run.
    std::vector<size_t> first_packet(poses.size() * views.size() + 1, 0);
    for (size_t i = 0; i + 1 < first_packet.size(); ++i)
      first_packet[i + 1] = first_packet[i] + (pixels[i % views.size()].size() + kPacketRays - 1) / kPacketRays;
    std::vector<double> partial(first_packet.back(), 0.0);
    for_each_projection(static_cast<const CpuVolume&>(handle), poses, views, pixels, params.projection,
                        [&](size_t image, size_t packet, const uint32_t* index, int count, const Eigen::Vector2f* g) {
                          const auto& dirs = edges[image % views.size()].directions;
                          double s = 0;
                          for (int i = 0; i < count; ++i) {
                            const float m = g[i].norm();
                            if (m > 0 && g[i].dot(dirs[index[i]]) >= cos_max * m) s += m;
                          }
                          partial[first_packet[image] + packet] = s;
                        });
    std::vector<double> scores(poses.size(), 0.0);
    for (size_t p = 0; p < poses.size(); ++p)
      for (size_t k = first_packet[p * views.size()]; k < first_packet[(p + 1) * views.size()]; ++k)
        scores[p] += partial[k];
    return scores;
  }

 private:
  // Runs the gradient projection of every (pose, view) pixel packet in parallel and hands each
  // packet's expected gradients to sink(image, packet, pixel_indices, count, gradients) (or
  // sink(image, pixel_indices, count, gradients)). Packets take pixels in tile order, whatever
  // the caller's order, so that the rays of one SIMD group stay close and skip empty space
  // together.
  template <class Sink>
  void for_each_projection(const CpuVolume& g, std::span<const Pose> poses,
                           std::span<const PinholeCamera> views,
                           std::span<const std::vector<Eigen::Vector2f>> pixels,
                           const ProjectionParams& params, Sink&& sink) {
    const PaddedGrid grid = g.grid();
    std::vector<std::vector<uint32_t>> order(views.size());
    for (size_t v = 0; v < views.size(); ++v) order[v] = tile_order(pixels[v]);
    const size_t n_images = poses.size() * views.size();
    std::vector<RaySetup> setups(n_images);
    struct Item { uint32_t image; uint32_t first; };
    std::vector<Item> items;
    for (size_t p = 0; p < poses.size(); ++p)
      for (size_t v = 0; v < views.size(); ++v) setups[p * views.size() + v] = make_ray_setup(g.geometry(), poses[p], views[v]);
    // Work in (view, packet, pose) order: the poses of a batch are usually close (a simplex, a
    // sweep around one estimate), so one packet's rays under consecutive poses read nearly the
    // same voxels, and they are still in cache.
    for (size_t v = 0; v < views.size(); ++v)
      for (size_t f = 0; f < pixels[v].size(); f += kPacketRays)
        for (size_t p = 0; p < poses.size(); ++p) items.push_back({uint32_t(p * views.size() + v), uint32_t(f)});
    tbb::parallel_for(size_t(0), items.size(), [&](size_t w) {
      const Item& it = items[w];
      const RaySetup& s = setups[it.image];
      const auto& px = pixels[it.image % views.size()];
      const uint32_t* index = order[it.image % views.size()].data() + it.first;
      const int count = int(std::min<size_t>(kPacketRays, px.size() - it.first));
      RayPacket packet;
      alignas(64) float inv_len[kPacketRays], gx[kPacketRays], gy[kPacketRays], gz[kPacketRays];
      fill_packet(s, count, params.step_mm, [&](int i) { return Eigen::Vector2d(px[index[i]].x(), px[index[i]].y()); },
                  packet, inv_len);
      march_by_entry(grid, packet, count, params.sampling == Sampling::nearest, gx, gy, gz);
      const Eigen::Vector3f au = s.axis_u.cast<float>(), av = s.axis_v.cast<float>();
      Eigen::Vector2f g2[kPacketRays];
      for (int i = 0; i < count; ++i) {
        const Eigen::Vector3f acc(gx[i], gy[i], gz[i]);
        g2[i] = Eigen::Vector2f(acc.dot(au), acc.dot(av)) * inv_len[i];
      }
      if constexpr (std::is_invocable_v<Sink, size_t, size_t, const uint32_t*, int, const Eigen::Vector2f*>)
        sink(it.image, it.first / kPacketRays, index, count, g2);
      else
        sink(it.image, index, count, g2);
    });
  }

};

}  // namespace

std::unique_ptr<Backend> make_cpu_backend() { return std::make_unique<CpuBackend>(); }
}  // namespace fluoro::cpu
