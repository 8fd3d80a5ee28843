// The synthetic CT phantoms: deterministic, correct geometry, the tissue values they promise, the
// optional fiducials and metal, and bone inside the central part of the field of view.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "datasets/phantom.hpp"
#include "engine/error.hpp"

namespace fluoro {
namespace {

Phantom make(PhantomKind kind, int size, uint64_t seed = 1, bool fiducials = false, bool metal = false) {
  PhantomParams p;
  p.kind = kind;
  p.size = size;
  p.seed = seed;
  p.fiducials = fiducials;
  p.metal_object = metal;
  return make_phantom(p);
}

double fraction_in(const Volume& v, float lo, float hi) {
  const auto n = std::count_if(v.voxels.begin(), v.voxels.end(), [&](float x) { return x >= lo && x <= hi; });
  return double(n) / double(v.voxels.size());
}

TEST(Phantom, IsDeterministicPerSeed) {
  for (const auto kind : {PhantomKind::femur, PhantomKind::pelvis}) {
    const Phantom a = make(kind, 48, 7), b = make(kind, 48, 7), c = make(kind, 48, 8);
    EXPECT_EQ(a.hu.voxels, b.hu.voxels);
    EXPECT_NE(a.hu.voxels, c.hu.voxels);
  }
}

TEST(Phantom, GeometryIsCentredIsotropicIdentity) {
  const Phantom p = make(PhantomKind::pelvis, 64);
  const auto& g = p.hu.geometry;
  EXPECT_EQ(g.size, Eigen::Vector3i(64, 64, 64));
  EXPECT_TRUE(g.spacing.isApprox(Eigen::Vector3d::Constant(256.0 / 64)));
  EXPECT_TRUE(g.direction.isIdentity());
  EXPECT_LT(g.physical_centre().norm(), 1e-9);
  EXPECT_EQ(p.hu.voxels.size(), g.voxel_count());
}

TEST(Phantom, FemurHasTheTissueValuesItPromises) {
  const Phantom p = make(PhantomKind::femur, 128);
  const Volume& v = p.hu;
  const auto [lo, hi] = std::minmax_element(v.voxels.begin(), v.voxels.end());
  EXPECT_NEAR(*lo, -1000.0f, 1.0f);   // air
  EXPECT_NEAR(*hi, 1500.0f, 1.0f);    // cortical bone is the densest tissue without implants
  EXPECT_EQ(v.at(0, 0, 0), -1000.0f);  // a corner is air
  EXPECT_GT(fraction_in(v, 39.0f, 41.0f), 0.10);      // soft tissue fills much of the volume
  EXPECT_GT(fraction_in(v, 1499.0f, 1501.0f), 0.001);  // a cortical shell
  EXPECT_GT(fraction_in(v, 299.0f, 301.0f), 0.001);    // marrow inside it
  EXPECT_TRUE(p.fiducials.empty());
}

TEST(Phantom, BoneLiesInTheCentralPartOfTheFieldOfView) {
  for (const auto kind : {PhantomKind::femur, PhantomKind::pelvis}) {
    const Phantom p = make(kind, 96);
    const auto& g = p.hu.geometry;
    Eigen::Vector3i lo = g.size, hi(-1, -1, -1);
    for (int k = 0; k < g.size.z(); ++k)
      for (int j = 0; j < g.size.y(); ++j)
        for (int i = 0; i < g.size.x(); ++i)
          if (p.hu.at(i, j, k) > 700) {
            lo = lo.cwiseMin(Eigen::Vector3i(i, j, k));
            hi = hi.cwiseMax(Eigen::Vector3i(i, j, k));
          }
    ASSERT_GE(hi.minCoeff(), 0) << "no bone";
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(lo[a], int(0.1 * 96)) << "axis " << a;
      EXPECT_LE(hi[a], int(0.9 * 96)) << "axis " << a;
      EXPECT_GT(hi[a] - lo[a], 96 / 8) << "axis " << a;  // and it is not a speck (a femur is ~5 cm deep)
    }
  }
}

TEST(Phantom, FiducialsAreDenseSpheresWhereItSays) {
  const Phantom p = make(PhantomKind::pelvis, 128, 3, true);
  ASSERT_GE(p.fiducials.size(), 4u);
  ASSERT_LE(p.fiducials.size(), 6u);
  EXPECT_GT(p.fiducial_radius_mm, 0.0);
  for (const auto& c : p.fiducials) {
    const Eigen::Vector3i idx = p.hu.geometry.physical_to_index(c).array().round().cast<int>();
    EXPECT_NEAR(p.hu.at(idx.x(), idx.y(), idx.z()), 2500.0f, 1.0f) << c.transpose();
  }
  for (size_t i = 0; i < p.fiducials.size(); ++i)
    for (size_t j = i + 1; j < p.fiducials.size(); ++j)
      EXPECT_GT((p.fiducials[i] - p.fiducials[j]).norm(), 2 * p.fiducial_radius_mm);
}

TEST(Phantom, MetalObjectIsTheDensestThing) {
  const Phantom without = make(PhantomKind::femur, 96, 5, false, false);
  const Phantom with = make(PhantomKind::femur, 96, 5, false, true);
  EXPECT_LT(*std::max_element(without.hu.voxels.begin(), without.hu.voxels.end()), 1501.0f);
  EXPECT_NEAR(*std::max_element(with.hu.voxels.begin(), with.hu.voxels.end()), 3000.0f, 1.0f);
  EXPECT_GT(fraction_in(with.hu, 2999.0f, 3001.0f), 1e-5);
}

TEST(Phantom, LargestSizeWorks) {
  const Phantom p = make(PhantomKind::pelvis, 256);
  EXPECT_EQ(p.hu.voxels.size(), size_t(256) * 256 * 256);
  EXPECT_GT(fraction_in(p.hu, 1499.0f, 1501.0f), 0.001);
}

TEST(Phantom, UnknownKindIsBadInput) {
  EXPECT_EQ(parse_phantom_kind("femur"), PhantomKind::femur);
  EXPECT_EQ(parse_phantom_kind("pelvis"), PhantomKind::pelvis);
  EXPECT_THROW(parse_phantom_kind("skull"), InputError);
}

}  // namespace
}  // namespace fluoro
