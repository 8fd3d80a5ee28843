// The cpu backend's SIMD ray marcher writes exactly the outputs it is asked for: guard bands
// around and past each output array come back untouched, for ray counts that are not multiples
// of the SIMD width.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "kernels/cpu/ray_march.hpp"

namespace fluoro::cpu {
namespace {

constexpr float kSentinel = -12345.0f;

TEST(KernelGuard, MarchersWriteExactlyCountOutputs) {
  // A 6^3 volume of ones, padded to 8^3: pairs of 16-bit quanta of 1 / 1000.
  const uint32_t pair = 1000u | (1000u << 16);
  std::vector<uint32_t> ones(8 * 8 * 8, pair);
  PaddedGrid grid;
  grid.component[0] = grid.component[1] = grid.component[2] = ones.data();
  grid.scale[0] = grid.scale[1] = grid.scale[2] = 1e-3f;
  grid.nx = grid.ny = grid.nz = 8;
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
    march_weighted_gradients(grid, rays, count, count % 2 == 0, gx.data() + kGuard, gy.data() + kGuard,
                             gz.data() + kGuard);  // nearest and trilinear reads alike
    for (int i = 0; i < int(out.size()); ++i) {
      const bool inside = i >= kGuard && i < kGuard + count;
      if (inside) {
        EXPECT_NEAR(out[size_t(i)], 5.0f, 1e-5f) << "count " << count << " ray " << i - kGuard;
        // sum_k t_k * 1 * h with t_k = (k + 0.5) h: h^2 * n^2 / 2 = 12.5
        EXPECT_NEAR(gx[size_t(i)], 12.5f, 1e-4f);
      } else {
        EXPECT_EQ(out[size_t(i)], kSentinel) << "count " << count << " index " << i;
        EXPECT_EQ(gx[size_t(i)], kSentinel);
        EXPECT_EQ(gy[size_t(i)], kSentinel);
        EXPECT_EQ(gz[size_t(i)], kSentinel);
      }
    }
  }
}

}  // namespace
}  // namespace fluoro::cpu
