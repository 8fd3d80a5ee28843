// The cpu backend's SIMD ray marcher writes exactly the outputs it is asked for: guard bands
// around and past each output array come back untouched, for ray counts that are not multiples
// of the SIMD width.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <vector>

#include <hwy/targets.h>

#include "kernels/cpu/cpu_volume.hpp"
#include "kernels/cpu/ray_march.hpp"

namespace fluoro::cpu {
namespace {

constexpr float kSentinel = -12345.0f;

TEST(KernelGuard, MarchersWriteExactlyCountOutputs) {
  // A 6^3 volume of ones, padded to 8^3: quads of 16-bit quanta of 1 / 1000.
  const uint64_t quad = 1000u * 0x0001000100010001ull;
  std::vector<uint64_t> ones(8 * 8 * 8, quad);
  PaddedGrid grid;
  grid.words = ones.data();
  grid.scale[0] = grid.scale[1] = grid.scale[2] = 1e-3f;
  grid.nx = grid.ny = grid.nz = 8;
  // The same ones as a gradient field: three components per voxel word (x, y, z, unused).
  std::vector<uint64_t> vector_ones(8 * 8 * 8, 1000u * 0x0000000100010001ull);
  PaddedGrid field = grid;
  field.words = vector_ones.data();
  field.vector_voxels = true;
  for (const int count : {1, 5, 16, 17, 63, 64}) {
    RayPacket rays{};
    for (int i = 0; i < count; ++i) {
      rays.entry_x[i] = 1.0f;
      rays.entry_y[i] = 1.5f + 0.05f * float(i);
      rays.entry_z[i] = 2.0f;
      rays.step_x[i] = 0.5f;  // h = 0.5 voxel along x
      rays.h[i] = 0.5f;
      rays.t0[i] = 0.0f;
      rays.n[i] = 10;  // 5 voxels of ones: the line integral is 5
    }
    constexpr int kGuard = 32;
    std::vector<float> out(kGuard + kPacketRays + kGuard, kSentinel);
    std::vector<float> gx(out), gy(out), gz(out);
    march_line_integrals(grid, rays, count, out.data() + kGuard);
    march_weighted_gradients(field, rays, count, count % 2 == 0, gx.data() + kGuard, gy.data() + kGuard,
                             gz.data() + kGuard);  // nearest and trilinear reads alike
    for (int i = 0; i < int(out.size()); ++i) {
      const bool inside = i >= kGuard && i < kGuard + count;
      if (inside) {
        EXPECT_NEAR(out[size_t(i)], 5.0f, 1e-5f) << "count " << count << " ray " << i - kGuard;
        // sum_k t_k * 1 * h with t_k = (k + 0.5) h: h^2 * n^2 / 2 = 12.5
        EXPECT_NEAR(gx[size_t(i)], 12.5f, 1e-4f);
        EXPECT_NEAR(gy[size_t(i)], 12.5f, 1e-4f);
        EXPECT_NEAR(gz[size_t(i)], 12.5f, 1e-4f);
      } else {
        EXPECT_EQ(out[size_t(i)], kSentinel) << "count " << count << " index " << i;
        EXPECT_EQ(gx[size_t(i)], kSentinel);
        EXPECT_EQ(gy[size_t(i)], kSentinel);
        EXPECT_EQ(gz[size_t(i)], kSentinel);
      }
    }
  }
}

// Empty-space leaping is exact: rays of assorted lengths and directions through a volume that is
// empty but for two small blobs give the same line integrals as plain scalar sampling at the same
// points (no skipping), including rays that end at a face while others in their group go on;
// with the bricks of fine voxels (4^3) and of coarse ones (2^3, brick_shift_for). A second volume
// of scattered single voxels puts empty bricks next to occupied ones everywhere, where a leap out of
// an empty brick one step too far lands on a non-zero sample.
TEST(KernelGuard, EmptySpaceLeapingSkipsOnlyZeros) {
  for (const bool scattered : {false, true})
  for (const double spacing_mm : {1.0, 3.0}) {
    SCOPED_TRACE(spacing_mm);
    SCOPED_TRACE(scattered ? "scattered voxels" : "two blobs");
    VolumeGeometry g;
    g.size = Eigen::Vector3i(37, 29, 41);
    g.spacing = Eigen::Vector3d::Constant(spacing_mm);
    std::vector<float> v(g.voxel_count(), 0.0f);
    auto blob = [&](Eigen::Vector3d c, double r) {
      for (int k = 0; k < g.size.z(); ++k)
        for (int j = 0; j < g.size.y(); ++j)
          for (int i = 0; i < g.size.x(); ++i)
            if ((Eigen::Vector3d(i, j, k) - c).norm() < r) v[g.linear_index(i, j, k)] = 1.0f + 0.01f * float(i);
    };
    if (scattered) {
      for (size_t i = 0; i < v.size(); ++i)
        if ((uint32_t(i) * 2654435761u) >> 24 == 0) v[i] = 1.0f + 0.001f * float(i % 97);  // 1 in 256, irregular
    } else {
      blob({5, 6, 7}, 2.5);
      blob({30, 22, 33}, 3.0);
    }
    const CpuVolume vol(g, nullptr, {v.data()});
    ASSERT_LT(vol.occupied_fraction(), scattered ? 0.8 : 0.5);  // leaping has room to act
    const PaddedGrid grid = vol.grid();
    EXPECT_EQ(grid.brick_shift, spacing_mm < 2.5 ? 2 : 1);
    RayPacket rays{};
    int count = 0;
    std::vector<Eigen::Vector3d> entries, steps;
    for (int i = 0; i < 61; ++i, ++count) {
      // Between two opposite corners, fanned out, with steps of 0.3 to 1.3 voxels.
      Eigen::Vector3d a(0.5 + 0.3 * (i % 7), 0.5 + 0.2 * (i % 5), 0.6);
      Eigen::Vector3d b(36.0 - 0.4 * (i % 3), 28.0 - 0.3 * (i % 4), 40.0 - 5.0 * (i % 6));
      if (i % 2) std::swap(a, b);  // half the rays move down every axis (leaps out through lower faces)
      const int n = 10 + 7 * (i % 9);
      const Eigen::Vector3d step = (b - a) / n;
      const Eigen::Vector3d entry = a + Eigen::Vector3d::Ones();  // padded coordinates
      rays.entry_x[i] = float(entry.x());
      rays.entry_y[i] = float(entry.y());
      rays.entry_z[i] = float(entry.z());
      rays.step_x[i] = float(step.x());
      rays.step_y[i] = float(step.y());
      rays.step_z[i] = float(step.z());
      rays.h[i] = 1.0f;
      rays.n[i] = n;
      entries.push_back(a);
      steps.push_back(step);
    }
    std::vector<float> out(kPacketRays, kSentinel);
    march_line_integrals(grid, rays, count, out.data());
    for (int i = 0; i < count; ++i) {
      double expected = 0;
      for (int k = 0; k < rays.n[i]; ++k) {
        const Eigen::Vector3d x = entries[size_t(i)] + (k + 0.5) * steps[size_t(i)];
        expected += vol.sample(0, float(x.x()), float(x.y()), float(x.z()));
      }
      EXPECT_NEAR(out[size_t(i)], expected, 1e-4 * (1 + expected)) << "ray " << i;
    }
    EXPECT_EQ(out[size_t(count)], kSentinel);
  }
}

// The marchers march a group of rays only over the steps at which one of them is inside the box
// of the occupied bricks (PaddedGrid::occupied_lo, _hi): exact, for rays that start or end inside
// it, graze its faces and edges, run parallel to an axis (step components of exactly 0 or about
// 1e-7 voxel) in and just outside its slabs, or never meet it; for both marchers and both brick
// sizes, and for a volume saved and loaded again (which recomputes the box from the brick map).
TEST(KernelGuard, TheOccupiedBoxBoundsTheMarchExactly) {
  for (const double spacing_mm : {1.0, 3.0}) {
    SCOPED_TRACE(spacing_mm);
    VolumeGeometry g;
    g.size = Eigen::Vector3i(40, 36, 44);
    g.spacing = Eigen::Vector3d::Constant(spacing_mm);
    const Eigen::Vector3d centre(21.3, 16.6, 24.2);
    const double radius = 5.2;
    std::vector<float> v(g.voxel_count(), 0.0f), gx(v), gy(v), gz(v);
    for (int k = 0; k < g.size.z(); ++k)
      for (int j = 0; j < g.size.y(); ++j)
        for (int i = 0; i < g.size.x(); ++i) {
          const Eigen::Vector3d d = Eigen::Vector3d(i, j, k) - centre;
          if (d.norm() >= radius) continue;
          const size_t n = g.linear_index(i, j, k);
          v[n] = 1.0f + 0.02f * float(i + 2 * j + 3 * k);
          gx[n] = float(d.x());
          gy[n] = float(-d.y());
          gz[n] = float(0.5 * d.z() + 1.0);
        }
    const CpuVolume scalar(g, nullptr, {v.data()});
    const CpuVolume field(g, nullptr, {gx.data(), gy.data(), gz.data()});
    const std::vector<uint8_t> saved = scalar.save();
    const CpuVolume loaded(g, nullptr, 1, saved, "test volume");
    const PaddedGrid grid = scalar.grid(), vector_grid = field.grid(), loaded_grid = loaded.grid();
    const int padded[3] = {g.size.x() + 2, g.size.y() + 2, g.size.z() + 2};
    for (int a = 0; a < 3; ++a) {
      // The box holds the blob (padded index = unpadded + 1) and is well inside the volume.
      EXPECT_LE(grid.occupied_lo[a], float(centre[a] - radius + 1));
      EXPECT_GE(grid.occupied_hi[a], float(centre[a] + radius + 1));
      EXPECT_GT(grid.occupied_lo[a], 4.0f);
      EXPECT_LT(grid.occupied_hi[a], float(padded[a] - 4));
      EXPECT_EQ(loaded_grid.occupied_lo[a], grid.occupied_lo[a]);
      EXPECT_EQ(loaded_grid.occupied_hi[a], grid.occupied_hi[a]);
    }
    RayPacket rays{};
    int count = 0;
    auto add = [&](Eigen::Vector3d from, Eigen::Vector3d step, int n) {
      ASSERT_LT(count, kPacketRays);
      rays.entry_x[count] = float(from.x());
      rays.entry_y[count] = float(from.y());
      rays.entry_z[count] = float(from.z());
      rays.step_x[count] = float(step.x());
      rays.step_y[count] = float(step.y());
      rays.step_z[count] = float(step.z());
      rays.h[count] = 0.5f;
      rays.t0[count] = 2.0f;
      rays.n[count] = n;
      ++count;
    };
    const Eigen::Vector3d c = centre + Eigen::Vector3d::Ones();  // padded
    const Eigen::Vector3d lo(grid.occupied_lo[0], grid.occupied_lo[1], grid.occupied_lo[2]);
    const Eigen::Vector3d hi(grid.occupied_hi[0], grid.occupied_hi[1], grid.occupied_hi[2]);
    uint32_t seed = 12345u;
    auto uniform = [&]() { return double((seed = seed * 1664525u + 1013904223u) >> 8) / double(1u << 24); };
    for (int i = 0; i < 24; ++i) {
      // Through points on the blob's rim and the box's faces, from outside the box, or starting
      // inside it (every third), in assorted directions and lengths.
      const Eigen::Vector3d dir = Eigen::Vector3d(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5).normalized();
      const Eigen::Vector3d rim = c + (radius - 0.3 + 0.6 * uniform()) * Eigen::Vector3d(dir.y(), -dir.x(), dir.z()).normalized();
      const Eigen::Vector3d face = lo + (hi - lo).cwiseProduct(Eigen::Vector3d(uniform(), uniform(), i % 4 ? 0.0 : 1.0));
      const Eigen::Vector3d through = i % 2 ? rim : face;
      const double h = 0.3 + 0.5 * uniform();
      const Eigen::Vector3d from = i % 3 == 0 ? through : through - 18.0 * dir;
      add(from, h * dir, i % 3 == 0 ? 20 : int(36.0 / h) - i % 5);  // some end inside the box
    }
    for (int a = 0; a < 3; ++a)
      for (const double offset : {0.0, radius - 0.5, hi[(a + 1) % 3] - c[(a + 1) % 3] - 0.01, hi[(a + 1) % 3] - c[(a + 1) % 3] + 1.5}) {
        // Along axis a, through the centre's row shifted along the next axis: through the blob,
        // its rim, just inside the box's slab and outside it; exactly parallel, and 1e-7 off.
        Eigen::Vector3d from = c, step = Eigen::Vector3d::Zero();
        from[(a + 1) % 3] += offset;
        from[a] = 1.0;
        step[a] = 0.45;
        add(from, step, int(double(padded[a] - 3) / 0.45));
        step[(a + 2) % 3] = 1e-7;
        add(from, step, int(double(padded[a] - 3) / 0.45));
      }
    add(Eigen::Vector3d(1.5, 1.5, 1.5), Eigen::Vector3d(0.4, 0.0, 0.0), 80);  // never meets the box
    std::vector<float> line(kPacketRays, kSentinel), reloaded(line), wx(line), wy(line), wz(line);
    march_line_integrals(grid, rays, count, line.data());
    march_line_integrals(loaded_grid, rays, count, reloaded.data());
    march_weighted_gradients(vector_grid, rays, count, false, wx.data(), wy.data(), wz.data());
    for (int i = 0; i < count; ++i) {
      double expected[4] = {0, 0, 0, 0};
      for (int k = 0; k < rays.n[i]; ++k) {
        const float kk = float(k) + 0.5f;
        const float t = rays.t0[i] + kk * rays.h[i];
        const float x = rays.entry_x[i] + kk * rays.step_x[i] - 1, y = rays.entry_y[i] + kk * rays.step_y[i] - 1,
                    z = rays.entry_z[i] + kk * rays.step_z[i] - 1;
        expected[0] += double(rays.h[i] * scalar.sample(0, x, y, z));
        for (int comp = 0; comp < 3; ++comp) expected[1 + comp] += double(rays.h[i] * t * field.sample(comp, x, y, z));
      }
      const float got[4] = {line[size_t(i)], wx[size_t(i)], wy[size_t(i)], wz[size_t(i)]};
      for (int o = 0; o < 4; ++o)
        EXPECT_NEAR(got[o], expected[o], 1e-4 * (1 + std::abs(expected[o]))) << "ray " << i << " output " << o;
      EXPECT_EQ(reloaded[size_t(i)], line[size_t(i)]) << "ray " << i;
    }
    EXPECT_EQ(line[size_t(count)], kSentinel);
  }
}

// Every SIMD target Highway compiled (AVX-512, AVX2, SSE4, scalar ...) reads the same voxels: the
// weighted gradient integrals of a signed three-component volume and the line integrals of its
// first component match plain scalar trilinear sampling at the same points, and nearest reads agree across targets, on
// each target the machine can run. Some rays run along the far y and z faces, where the last
// padded row (the replicated one) is read.
TEST(KernelGuard, EverySimdTargetMatchesScalarSampling) {
  VolumeGeometry g;
  g.size = Eigen::Vector3i(19, 23, 17);
  std::vector<std::vector<float>> comps(3, std::vector<float>(g.voxel_count()));
  for (int k = 0; k < g.size.z(); ++k)
    for (int j = 0; j < g.size.y(); ++j)
      for (int i = 0; i < g.size.x(); ++i)
        for (int c = 0; c < 3; ++c)
          comps[size_t(c)][g.linear_index(i, j, k)] = float(std::sin(0.7 * i + 1.3 * c) * std::cos(0.5 * j - 0.9 * k) + 0.1 * c);
  const CpuVolume vol(g, nullptr, {comps[0].data(), comps[1].data(), comps[2].data()});
  const CpuVolume first(g, nullptr, {comps[0].data()});  // the line integrals read scalar volumes
  const PaddedGrid field = vol.grid(), grid = first.grid();
  RayPacket rays{};
  const int count = 53;
  for (int i = 0; i < count; ++i) {
    const bool far_face = i >= 45;  // from near the far y face outwards, clamped onto it
    rays.entry_x[i] = 0.7f + 0.37f * float(i % 11);
    rays.entry_y[i] = far_face ? 21.5f + 0.1f * float(i % 7) : 0.9f + 0.41f * float(i % 13);
    rays.entry_z[i] = far_face ? 14.0f : 0.6f;
    rays.step_x[i] = 0.21f + 0.01f * float(i % 5);
    rays.step_y[i] = far_face ? 0.25f : 0.17f - 0.02f * float(i % 3);
    rays.step_z[i] = far_face ? 0.15f : 0.29f;
    rays.h[i] = 0.5f;
    rays.t0[i] = 3.0f;
    rays.n[i] = far_face ? 30 : 20 + i;
  }
  std::vector<std::array<double, 4>> expected(count);  // three weighted gradients, line integral
  for (int i = 0; i < count; ++i)
    for (int k = 0; k < rays.n[i]; ++k) {
      const float kk = float(k) + 0.5f;
      const float t = rays.t0[i] + kk * rays.h[i];
      // Padded to unpadded index space: minus one voxel.
      const float x = rays.entry_x[i] + kk * rays.step_x[i] - 1, y = rays.entry_y[i] + kk * rays.step_y[i] - 1,
                  z = rays.entry_z[i] + kk * rays.step_z[i] - 1;
      for (int c = 0; c < 3; ++c) expected[size_t(i)][size_t(c)] += double(rays.h[i] * t * vol.sample(c, x, y, z));
      expected[size_t(i)][3] += double(rays.h[i] * vol.sample(0, x, y, z));
    }
  const std::vector<int64_t> targets = hwy::SupportedAndGeneratedTargets();
  ASSERT_GT(targets.size(), 1u);
  std::vector<float> first_nearest;
  for (const int64_t target : targets) {
    hwy::SetSupportedTargetsForTest(target);
    const char* name = hwy::TargetName(target);
    std::vector<float> out[4], nearest[3];
    for (auto& o : out) o.assign(kPacketRays, kSentinel);
    for (auto& o : nearest) o.assign(kPacketRays, kSentinel);
    march_weighted_gradients(field, rays, count, false, out[0].data(), out[1].data(), out[2].data());
    march_line_integrals(grid, rays, count, out[3].data());
    march_weighted_gradients(field, rays, count, true, nearest[0].data(), nearest[1].data(), nearest[2].data());
    for (int i = 0; i < count; ++i)
      for (int c = 0; c < 4; ++c) {
        const double e = expected[size_t(i)][size_t(c)];
        EXPECT_NEAR(out[c][size_t(i)], e, 1e-4 * (1 + std::abs(e))) << name << " ray " << i << " output " << c;
      }
    for (auto& o : out) EXPECT_EQ(o[size_t(count)], kSentinel) << name;
    std::vector<float> all_nearest;
    for (auto& o : nearest) all_nearest.insert(all_nearest.end(), o.begin(), o.begin() + count);
    if (first_nearest.empty()) first_nearest = all_nearest;
    for (size_t i = 0; i < all_nearest.size(); ++i)
      EXPECT_NEAR(all_nearest[i], first_nearest[i], 1e-4 * (1 + std::abs(first_nearest[i]))) << name << " nearest " << i;
  }
  hwy::SetSupportedTargetsForTest(0);  // back to what the machine supports
}

}  // namespace
}  // namespace fluoro::cpu
