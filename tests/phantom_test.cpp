// Synthetic CT phantoms: determinism, geometry, tissue values, fiducials, metal, placement.
// The 256^3 case is a single make_phantom call (about 1 s optimised; much slower under sanitizers).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "datasets/phantom.hpp"
#include "engine/error.hpp"

namespace fluoro {
namespace {

PhantomParams params(PhantomKind kind, int size, uint64_t seed = 1, bool fiducials = false, bool metal = false) {
  PhantomParams p;
  p.kind = kind;
  p.size = size;
  p.seed = seed;
  p.fiducials = fiducials;
  p.metal_object = metal;
  return p;
}

struct IndexBox {
  std::array<int, 3> lo{1 << 30, 1 << 30, 1 << 30}, hi{-1, -1, -1};
  bool empty() const { return hi[0] < 0; }
};

// Bounding box (voxel indices) of the voxels above `threshold` HU.
IndexBox box_above(const Volume& v, float threshold) {
  IndexBox b;
  const auto& n = v.geometry.size;
  for (int k = 0; k < n.z(); ++k)
    for (int j = 0; j < n.y(); ++j)
      for (int i = 0; i < n.x(); ++i)
        if (v.at(i, j, k) > threshold) {
          const int a[3] = {i, j, k};
          for (int d = 0; d < 3; ++d) {
            b.lo[d] = std::min(b.lo[d], a[d]);
            b.hi[d] = std::max(b.hi[d], a[d]);
          }
        }
  return b;
}

void expect_centred_geometry(const Phantom& ph, int n, double fov) {
  const VolumeGeometry& g = ph.hu.geometry;
  EXPECT_EQ(g.size, Eigen::Vector3i(n, n, n));
  EXPECT_EQ(ph.hu.voxels.size(), size_t(n) * n * n);
  const double h = fov / n;
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(g.spacing[a], h, 1e-12);
    EXPECT_NEAR(g.origin[a], -0.5 * (n - 1) * h, 1e-9);
  }
  EXPECT_TRUE(g.direction.isApprox(Eigen::Matrix3d::Identity(), 0.0));
  EXPECT_LT(g.physical_centre().norm(), 1e-9);
  EXPECT_NO_THROW(validate_volume(ph.hu, "phantom"));
}

void expect_bone_in_central_80_percent(const Volume& v) {
  const IndexBox b = box_above(v, 700.0f);
  ASSERT_FALSE(b.empty());
  for (int d = 0; d < 3; ++d) {
    const int n = v.geometry.size[d];
    EXPECT_GE(b.lo[d], 0.1 * n) << "axis " << d;
    EXPECT_LE(b.hi[d], 0.9 * n) << "axis " << d;
    EXPECT_GT(b.hi[d] - b.lo[d], 0.15 * n) << "axis " << d;  // a real structure, not a speck
  }
}

void expect_air_corners(const Volume& v) {
  const int n = v.geometry.size.x() - 1;
  for (int c = 0; c < 8; ++c)
    EXPECT_EQ(v.at((c & 1) ? n : 0, (c & 2) ? n : 0, (c & 4) ? n : 0), -1000.0f) << "corner " << c;
}

size_t count_equal(const Volume& v, float value) {
  return size_t(std::count(v.voxels.begin(), v.voxels.end(), value));
}

TEST(Phantom, ParsesKinds) {
  EXPECT_EQ(parse_phantom_kind("femur"), PhantomKind::femur);
  EXPECT_EQ(parse_phantom_kind("pelvis"), PhantomKind::pelvis);
  EXPECT_EQ(parse_phantom_kind("head"), PhantomKind::head);
  try {
    parse_phantom_kind("skull");
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--kind skull"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("unknown phantom kind"), std::string::npos) << e.what();
  }
}

TEST(Phantom, RejectsBadParameters) {
  PhantomParams p = params(PhantomKind::femur, 0);
  EXPECT_THROW(make_phantom(p), InputError);
  p.size = 32;
  p.fov_mm = -1;
  EXPECT_THROW(make_phantom(p), InputError);
}

TEST(Phantom, IsDeterministicAndSeeded) {
  for (PhantomKind kind : {PhantomKind::femur, PhantomKind::pelvis, PhantomKind::head}) {
    const Phantom a = make_phantom(params(kind, 64, 5, true, true));
    const Phantom b = make_phantom(params(kind, 64, 5, true, true));
    EXPECT_TRUE(a.hu.voxels == b.hu.voxels);
    ASSERT_EQ(a.fiducials.size(), b.fiducials.size());
    for (size_t f = 0; f < a.fiducials.size(); ++f) EXPECT_EQ(a.fiducials[f], b.fiducials[f]);
    const Phantom c = make_phantom(params(kind, 64, 6, true, true));
    EXPECT_FALSE(a.hu.voxels == c.hu.voxels);
  }
}

TEST(Phantom, ShapeDoesNotDependOnTheExtras) {
  // Fiducials and metal are drawn after the bone, so the bone of a seed is the same either way.
  const Phantom plain = make_phantom(params(PhantomKind::femur, 64, 3));
  const Phantom extras = make_phantom(params(PhantomKind::femur, 64, 3, true, true));
  size_t differing = 0;
  for (size_t n = 0; n < plain.hu.voxels.size(); ++n) differing += plain.hu.voxels[n] != extras.hu.voxels[n];
  EXPECT_GT(differing, 0u);
  EXPECT_LT(differing, plain.hu.voxels.size() / 200);  // only around the spheres and the screw
}

TEST(Phantom, FemurGeometryAndTissues) {
  const int n = 128;
  const Phantom ph = make_phantom(params(PhantomKind::femur, n));
  expect_centred_geometry(ph, n, 256.0);
  const Volume& v = ph.hu;
  const auto [mn, mx] = std::minmax_element(v.voxels.begin(), v.voxels.end());
  EXPECT_EQ(*mn, -1000.0f);
  EXPECT_NEAR(*mx, 1500.0f, 0.5f);
  EXPECT_TRUE(ph.fiducials.empty());
  EXPECT_EQ(ph.fiducial_radius_mm, 0.0);
  expect_air_corners(v);
  EXPECT_GT(count_equal(v, 40.0f), size_t(n) * n * n / 10);  // the thigh
  EXPECT_GT(count_equal(v, 1500.0f), 1000u);
  EXPECT_GT(count_equal(v, 300.0f), 1000u);

  // Mid-length axial slice: a hollow shaft, marrow at the centre of the cortical ring.
  const int k = n / 2;
  int lo[2] = {n, n}, hi[2] = {-1, -1};
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      if (v.at(i, j, k) > 700.0f) {
        lo[0] = std::min(lo[0], i), hi[0] = std::max(hi[0], i);
        lo[1] = std::min(lo[1], j), hi[1] = std::max(hi[1], j);
      }
  ASSERT_GE(hi[0], 0);
  const double h = v.geometry.spacing.x();
  // The shaft is 23 to 30 mm wide and its cortex 4 to 6 mm thick at a 256 mm field of view.
  EXPECT_GT((hi[0] - lo[0] + 1) * h, 20.0);
  EXPECT_LT((hi[0] - lo[0] + 1) * h, 34.0);
  EXPECT_NEAR(v.at((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, k), 300.0f, 1.0f);
  int cortex = 0;  // cortical voxels along the row through the centre, both walls
  for (int i = lo[0]; i <= hi[0]; ++i) cortex += v.at(i, (lo[1] + hi[1]) / 2, k) > 700.0f;
  EXPECT_GE(cortex * h / 2, 3.0);
  EXPECT_LE(cortex * h / 2, 7.0);

  expect_bone_in_central_80_percent(v);
  // A long bone along k.
  const IndexBox b = box_above(v, 700.0f);
  EXPECT_GT(b.hi[2] - b.lo[2], 0.6 * n);
  EXPECT_GT(b.hi[2] - b.lo[2], 2 * (b.hi[0] - b.lo[0]));
}

TEST(Phantom, PelvisTissuesAndPlacement) {
  const int n = 128;
  const Phantom ph = make_phantom(params(PhantomKind::pelvis, n, 2));
  expect_centred_geometry(ph, n, 256.0);
  const Volume& v = ph.hu;
  const auto [mn, mx] = std::minmax_element(v.voxels.begin(), v.voxels.end());
  EXPECT_EQ(*mn, -1000.0f);
  EXPECT_NEAR(*mx, 1500.0f, 0.5f);
  expect_air_corners(v);
  EXPECT_GT(count_equal(v, 40.0f), size_t(n) * n * n / 10);
  EXPECT_GT(count_equal(v, 1500.0f), 1000u);
  EXPECT_GT(count_equal(v, 300.0f), 1000u);
  expect_bone_in_central_80_percent(v);
  // Wider than deep: two hemipelves left and right.
  const IndexBox b = box_above(v, 700.0f);
  EXPECT_GT(b.hi[0] - b.lo[0], 0.55 * n);
  EXPECT_GT(b.hi[0] - b.lo[0], b.hi[1] - b.lo[1]);
  // Bilateral and nearly symmetric: as much bone right (-x) as left (+x) of the midline.
  size_t right = 0, left = 0;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        if (v.at(i, j, k) > 700.0f) (i < n / 2 ? right : left) += 1;
  EXPECT_GT(right, 2000u);
  EXPECT_NEAR(double(right) / double(left), 1.0, 0.15);
}

void expect_fiducials(const Phantom& ph) {
  ASSERT_GE(ph.fiducials.size(), 4u);
  ASSERT_LE(ph.fiducials.size(), 6u);
  EXPECT_NEAR(ph.fiducial_radius_mm, 2.0, 0.5);
  const Volume& v = ph.hu;
  for (size_t f = 0; f < ph.fiducials.size(); ++f) {
    const Eigen::Vector3d idx = v.geometry.physical_to_index(ph.fiducials[f]);
    const Eigen::Vector3i r(int(std::lround(idx.x())), int(std::lround(idx.y())), int(std::lround(idx.z())));
    ASSERT_TRUE((r.array() >= 0).all() && (r.array() < v.geometry.size.array()).all());
    EXPECT_NEAR(v.at(r.x(), r.y(), r.z()), 2500.0f, 1.0f) << "fiducial " << f;
    for (size_t g = 0; g < f; ++g)
      EXPECT_GT((ph.fiducials[f] - ph.fiducials[g]).norm(), 2.0 * ph.fiducial_radius_mm + 2.0);
  }
}

TEST(Phantom, Fiducials) {
  expect_fiducials(make_phantom(params(PhantomKind::pelvis, 96, 1, true)));
  expect_fiducials(make_phantom(params(PhantomKind::femur, 64, 9, true, true)));
  expect_fiducials(make_phantom(params(PhantomKind::pelvis, 64, 9, true, true)));
  expect_fiducials(make_phantom(params(PhantomKind::head, 64, 1, true, true)));
  // Fiducials sit near the bone: a cortical voxel within 6 mm of each centre.
  const Phantom ph = make_phantom(params(PhantomKind::femur, 128, 4, true));
  expect_fiducials(ph);
  const Volume& v = ph.hu;
  for (const auto& c : ph.fiducials) {
    bool near_bone = false;
    const Eigen::Vector3d idx = v.geometry.physical_to_index(c);
    for (int dk = -3; dk <= 3; ++dk)
      for (int dj = -3; dj <= 3; ++dj)
        for (int di = -3; di <= 3; ++di) {
          const int i = int(std::lround(idx.x())) + di, j = int(std::lround(idx.y())) + dj,
                    k = int(std::lround(idx.z())) + dk;
          const float value = v.at(i, j, k);
          near_bone = near_bone || (value > 1200.0f && value < 1600.0f);
        }
    EXPECT_TRUE(near_bone) << c.transpose();
  }
}

TEST(Phantom, MetalObject) {
  // A rod of radius 3 mm and length 60 mm holds ~1700 mm^3, ~200 voxels of 8 mm^3.
  const Phantom femur = make_phantom(params(PhantomKind::femur, 128, 1, false, true));
  const size_t metal = count_equal(femur.hu, 3000.0f);
  EXPECT_GT(metal, 60u);
  EXPECT_LT(metal, 600u);
  expect_bone_in_central_80_percent(femur.hu);
  auto count_above = [](const Volume& v, float t) {
    return size_t(std::count_if(v.voxels.begin(), v.voxels.end(), [t](float x) { return x > t; }));
  };
  // At 4 mm voxels the rod is mostly partial volume, but it is there, and only with the option.
  const Phantom pelvis = make_phantom(params(PhantomKind::pelvis, 64, 1, false, true));
  EXPECT_GT(count_above(pelvis.hu, 1600.0f), 8u);
  EXPECT_EQ(count_above(make_phantom(params(PhantomKind::pelvis, 64, 1)).hu, 1600.0f), 0u);
  EXPECT_EQ(count_above(make_phantom(params(PhantomKind::femur, 64, 1)).hu, 1600.0f), 0u);
}

TEST(Phantom, AntiAliasedEdges) {
  // Supersampled interface voxels take intermediate values (2x2x2: multiples of 1/8 of a step).
  const Phantom ph = make_phantom(params(PhantomKind::femur, 64));
  size_t mixed = 0;
  for (float x : ph.hu.voxels) mixed += x != -1000.0f && x != 40.0f && x != 300.0f && x != 1500.0f;
  EXPECT_GT(mixed, 1000u);
}

TEST(Phantom, SmallAndLargeSizes) {
  const Phantom small = make_phantom(params(PhantomKind::pelvis, 64, 11));
  expect_centred_geometry(small, 64, 256.0);
  expect_bone_in_central_80_percent(small.hu);

  // One 256^3 call only: slow under sanitizers.
  const Phantom large = make_phantom(params(PhantomKind::femur, 256, 1, true, true));
  expect_centred_geometry(large, 256, 256.0);
  expect_bone_in_central_80_percent(large.hu);
  expect_fiducials(large);
  EXPECT_GT(count_equal(large.hu, 3000.0f), 500u);
}

TEST(Phantom, AnatomyScalesWithTheFieldOfView) {
  PhantomParams p = params(PhantomKind::femur, 64);
  p.fov_mm = 180.0;
  const Phantom ph = make_phantom(p);
  expect_centred_geometry(ph, 64, 180.0);
  expect_bone_in_central_80_percent(ph.hu);
}

}  // namespace
}  // namespace fluoro
