// Op::gradient_floor (engine/ops.hpp): the reference backend's definition, the bound on what it
// changes in the expected gradients and the GPR score, and the cpu backend's empty space.
#include <gtest/gtest.h>

#include <cmath>

#include "engine/backend.hpp"
#include "engine/error.hpp"
#include "engine/ray_setup.hpp"
#include "kernels/backend_registry.hpp"
#include "kernels/cpu/cpu_volume.hpp"
#include "tests/test_scenes.hpp"

namespace fluoro {
namespace {

// A bone-like ball: a strong edge (the cortex) around an interior whose attenuation ripples
// weakly (cancellous texture), on an anisotropic oblique grid.
Volume textured_ball() {
  const Eigen::Matrix3d D = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, -1).normalized()).toRotationMatrix();
  return test::make_volume({37, 33, 29}, {1.3, 1.5, 1.7}, [](const Eigen::Vector3d& x) {
    if (x.norm() > 17) return 0.0f;
    return float(0.03 + 0.0015 * std::sin(0.9 * x.x()) * std::cos(0.7 * x.y() + 0.5 * x.z()));
  }, D);
}

std::vector<PinholeCamera> views() {
  return {test::camera_looking_at_origin(300, 400, 41, 37, Eigen::Vector3d(0.3, 0.2, 1)),
          test::camera_looking_at_origin(300, 400, 29, 43, Eigen::Vector3d(1, 0.1, 0.2))};
}

const Pose kPose = pose_from_rotation_vector(Eigen::Vector3d(0.1, -0.2, 0.15), Eigen::Vector3d(1, -2, 0.5));

// Every pixel of each view (the bound must hold on all of them, not only on edges).
std::vector<std::vector<Eigen::Vector2f>> all_pixels(const std::vector<PinholeCamera>& cams) {
  std::vector<std::vector<Eigen::Vector2f>> px(cams.size());
  for (size_t v = 0; v < cams.size(); ++v)
    for (int y = 0; y < cams[v].height; ++y)
      for (int x = 0; x < cams[v].width; ++x) px[v].emplace_back(float(x) + 0.5f, float(y) + 0.25f);
  return px;
}

double largest_magnitude(const VectorField& f) {
  double m = 0;
  for (const auto& v : f.vectors) m = std::max(m, double(Eigen::Vector3f(v[0], v[1], v[2]).norm()));
  return m;
}

// The reference backend zeroes exactly the voxels below the floor and keeps the rest as they were.
TEST(GradientFloor, ReferenceZeroesExactlyTheWeakVoxels) {
  auto ref = make_backend("reference");
  const auto field = ref->gradient_field(*ref->upload(textured_ball()), {1.0, 0.0});
  const VectorField before = ref->download_gradient(*field);
  const VectorField after = ref->download_gradient(*ref->floor_gradient(*field, {0.1}));
  const double floor = 0.1 * largest_magnitude(before);
  size_t zeroed = 0, kept = 0;
  for (size_t n = 0; n < before.vectors.size(); ++n) {
    const Eigen::Vector3f b(before.vectors[n][0], before.vectors[n][1], before.vectors[n][2]);
    const Eigen::Vector3f a(after.vectors[n][0], after.vectors[n][1], after.vectors[n][2]);
    if (b.norm() < floor) {
      EXPECT_EQ(a, Eigen::Vector3f::Zero()) << n;
      zeroed += b.norm() > 0;
    } else {
      EXPECT_EQ(a, b) << n;
      ++kept;
    }
  }
  // The ripples are weak but not nothing: the floor has work to do, and the cortex survives.
  EXPECT_GT(zeroed, before.vectors.size() / 20);
  EXPECT_GT(kept, 100u);
}

// A sample of the floored field moves by less than the floor f, so pixel p's expected gradient
// moves by at most f * h * sum_k t_k * |K^-1 p|^-1 * ||(axis_u, axis_v)||, and an ungated GPR
// score (max_angle 180 degrees) by at most the sum of those.
TEST(GradientFloor, ChangesTheExpectedGradientsWithinTheBound) {
  auto ref = make_backend("reference");
  const Volume mu = textured_ball();
  const auto field = ref->gradient_field(*ref->upload(mu), {1.0, 0.0});
  constexpr double kRelative = 0.1;
  const auto floored = ref->floor_gradient(*field, {kRelative});
  const double floor = kRelative * largest_magnitude(ref->download_gradient(*field));
  const auto cams = views();
  const auto pixels = all_pixels(cams);
  const ProjectionParams pp{0.8, Sampling::trilinear};
  const auto e0 = ref->gradient_projection(*field, std::span(&kPose, 1), cams, pixels, pp);
  const auto e1 = ref->gradient_projection(*floored, std::span(&kPose, 1), cams, pixels, pp);
  double bound_sum = 0, worst_ratio = 0, largest_change = 0;
  std::vector<EdgePixels> edges(cams.size());
  for (size_t v = 0; v < cams.size(); ++v) {
    const RaySetup s = make_ray_setup(mu.geometry, kPose, cams[v]);
    const double axes = std::sqrt(s.axis_u.squaredNorm() + s.axis_v.squaredNorm());  // >= the operator norm
    for (size_t i = 0; i < pixels[v].size(); ++i) {
      const PixelRay r = make_pixel_ray(s, pixels[v][i].x(), pixels[v][i].y(), pp.step_mm);
      const double weights = r.n * r.t0 + r.h * r.n * r.n / 2.0;  // sum_k t0 + (k + 0.5) h
      const double bound = floor * r.h * weights * r.inv_len * axes;
      const double change = (e1[v][i] - e0[v][i]).cast<double>().norm();
      // float outputs: a relative rounding allowance on top of the bound.
      EXPECT_LE(change, bound * (1 + 1e-5) + 1e-6 * e0[v][i].norm()) << "view " << v << " pixel " << i;
      if (bound > 0) worst_ratio = std::max(worst_ratio, change / bound);
      largest_change = std::max(largest_change, change);
      bound_sum += bound;
    }
    edges[v].pixels = pixels[v];
    edges[v].directions.assign(pixels[v].size(), Eigen::Vector2f(1, 0));
  }
  EXPECT_GT(largest_change, 0);  // the floor did change something the bound had to cover
  EXPECT_GT(worst_ratio, 0.01);   // and the bound is not vacuous by orders of magnitude
  const GprParams ungated{pp, 180.0};
  const double s0 = ref->gpr_score(*field, std::span(&kPose, 1), cams, edges, ungated)[0];
  const double s1 = ref->gpr_score(*floored, std::span(&kPose, 1), cams, edges, ungated)[0];
  EXPECT_LE(std::abs(s1 - s0), bound_sum);
}

TEST(GradientFloor, ToleranceOutsideZeroToOneIsBadInputAndZeroChangesNothing) {
  for (const char* name : {"reference", "cpu"}) {
    auto b = make_backend(name);
    const auto field = b->gradient_field(*b->upload(textured_ball()), {1.0, 0.0});
    EXPECT_THROW(b->floor_gradient(*field, {-0.1}), InputError) << name;
    EXPECT_THROW(b->floor_gradient(*field, {1.0}), InputError) << name;
    EXPECT_THROW(b->floor_gradient(*field, {std::nan("")}), InputError) << name;
    const VectorField before = b->download_gradient(*field);
    const VectorField after = b->download_gradient(*b->floor_gradient(*field, {0.0}));
    EXPECT_EQ(before.vectors, after.vectors) << name;
  }
}

// The cpu backend's floored field: what the floor zeroes becomes empty space its marchers skip.
TEST(GradientFloor, CpuFloorEmptiesBricks) {
  auto cpu = make_backend("cpu");
  const auto field = cpu->gradient_field(*cpu->upload(textured_ball()), {1.0, 0.0});
  const auto floored = cpu->floor_gradient(*field, {0.1});
  const double before = static_cast<const cpu::CpuVolume&>(*field).occupied_fraction();
  const double after = static_cast<const cpu::CpuVolume&>(*floored).occupied_fraction();
  EXPECT_LT(after, 0.8 * before);
  EXPECT_GT(after, 0.0);
}

}  // namespace
}  // namespace fluoro
