// The batched ray setup (make_pixel_rays) against the per-pixel one (make_pixel_ray), which every
// backend shares: the same rays bit for bit, so the cpu backend marches what the others march.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "datasets/c_arm.hpp"
#include "engine/ray_setup.hpp"

namespace fluoro {
namespace {

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

TEST(RaySetup, BatchedRaysAreThePerPixelRaysBitForBit) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> angle(-0.6, 0.6), shift(-80, 80), unit(0, 1);
  int compared = 0, misses = 0;
  for (int scene = 0; scene < 6; ++scene) {
    // An anisotropic, oblique CT grid and a C-arm view at a random pose.
    VolumeGeometry g;
    g.size = Eigen::Vector3i(60 + 20 * scene, 90, 45);
    g.spacing = Eigen::Vector3d(0.8, 1.1, 2.5 + 0.1 * scene);
    g.direction = Eigen::AngleAxisd(angle(rng), Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    // The box about the isocentre, give or take a few centimetres.
    g.origin = -g.direction * (g.size.cast<double>().cwiseProduct(g.spacing) * 0.5) +
               Eigen::Vector3d(shift(rng), shift(rng), shift(rng)) * 0.25;
    CArmGeometry c;
    c.pixels = 97;
    const PinholeCamera cam = c_arm_view(c, 40.0 * scene, scene % 2 ? 15.0 : 0.0);
    const Pose pose = pose_from_rotation_vector(Eigen::Vector3d(angle(rng), angle(rng), angle(rng)),
                                                Eigen::Vector3d(shift(rng), shift(rng), shift(rng)) * 0.25);
    const RaySetup s = make_ray_setup(g, pose, cam);
    // Whole pixels, fractions, pixels beyond the image (rays that miss) and a NaN: 150 of them,
    // more than one chunk of 16 and not a multiple of it.
    std::vector<double> u, v;
    for (int i = 0; i < 149; ++i) {
      u.push_back(i % 3 ? double(i % 97) : -300 + 800 * unit(rng));
      v.push_back(i % 5 ? double(i / 3) + 0.25 : -300 + 800 * unit(rng));
    }
    u.push_back(std::numeric_limits<double>::quiet_NaN());
    v.push_back(3);
    const double step = 0.7 + 0.3 * scene;
    // A cpu packet's 64 pixels and a short tail of 5, batched alone, are the same rays as in the
    // whole batch below.
    std::vector<PixelRay> batched(u.size()), packet(64), tail(5);
    make_pixel_rays(s, u.data(), v.data(), int(u.size()), step, batched.data());
    make_pixel_rays(s, u.data() + 70, v.data() + 70, 64, step, packet.data());
    make_pixel_rays(s, u.data() + 140, v.data() + 140, 5, step, tail.data());
    for (int i = 0; i < 64; ++i) EXPECT_TRUE(same_bits(packet[size_t(i)].t0, batched[size_t(70 + i)].t0));
    for (int i = 0; i < 5; ++i) EXPECT_TRUE(same_bits(tail[size_t(i)].h, batched[size_t(140 + i)].h));
    for (size_t i = 0; i < u.size(); ++i) {
      const PixelRay one = make_pixel_ray(s, u[i], v[i], step);
      const PixelRay& b = batched[i];
      EXPECT_EQ(b.n, one.n) << "scene " << scene << ", pixel " << i;
      EXPECT_TRUE(same_bits(b.t0, one.t0) && same_bits(b.h, one.h) && same_bits(b.inv_len, one.inv_len))
          << "scene " << scene << ", pixel " << i;
      for (int a = 0; a < 3; ++a) EXPECT_TRUE(same_bits(b.dir[a], one.dir[a])) << "scene " << scene << ", pixel " << i;
      ++compared;
      misses += one.n == 0;
    }
  }
  EXPECT_EQ(compared, 6 * 150);
  EXPECT_GT(misses, 6);            // rays that miss the box were among them ...
  EXPECT_LT(misses, compared / 2); // ... and most hit it
}

}  // namespace
}  // namespace fluoro
