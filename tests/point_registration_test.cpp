// Landmark registration: Horn's closed form is exact on exact correspondences, weights do what
// they say, degenerate inputs are refused; triangulation recovers points seen by calibrated views.
#include <gtest/gtest.h>

#include <random>

#include "engine/random_draws.hpp"
#include "datasets/c_arm.hpp"
#include "engine/error.hpp"
#include "pipelines/registration/point_registration.hpp"
#include "pipelines/registration/triangulation.hpp"

namespace fluoro {
namespace {

std::vector<Eigen::Vector3d> random_points(int n, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-80, 80);
  std::vector<Eigen::Vector3d> p;
  for (int i = 0; i < n; ++i) p.push_back(draw3(u, rng));
  return p;
}

TEST(PointRegistration, ExactOnExactCorrespondences) {
  std::mt19937 rng(3);
  std::normal_distribution<double> g(0, 1);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d t = draw3(g, rng) * 50;  // the second argument first, as GCC evaluated it
    const Pose truth = pose_from_rotation_vector(draw3(g, rng), t);
    const auto from = random_points(3 + trial % 6, rng);
    std::vector<Eigen::Vector3d> to;
    for (const auto& p : from) to.push_back(truth * p);
    const PointRegistration r = register_points(from, to, {}, "test");
    EXPECT_LT((r.transform.matrix() - truth.matrix()).norm(), 1e-9) << trial;
    EXPECT_LT(r.rms_mm, 1e-9);
    EXPECT_NEAR(r.transform.linear().determinant(), 1.0, 1e-12);  // a rotation, never a reflection
  }
}

TEST(PointRegistration, ZeroWeightIgnoresAnOutlier) {
  std::mt19937 rng(5);
  const Pose truth = pose_from_rotation_vector(Eigen::Vector3d(0.3, -0.2, 0.5), Eigen::Vector3d(10, 20, -5));
  const auto from = random_points(6, rng);
  std::vector<Eigen::Vector3d> to;
  for (const auto& p : from) to.push_back(truth * p);
  to[2] += Eigen::Vector3d(40, 0, 0);  // a mislabelled landmark
  const PointRegistration unweighted = register_points(from, to, {}, "test");
  const PointRegistration weighted = register_points(from, to, {1, 1, 0, 1, 1, 1}, "test");
  EXPECT_GT((unweighted.transform.matrix() - truth.matrix()).norm(), 1e-2);
  EXPECT_LT((weighted.transform.matrix() - truth.matrix()).norm(), 1e-9);
  EXPECT_NEAR(weighted.max_mm, 40.0, 1e-6);  // the outlier's residual is still reported
}

TEST(PointRegistration, NoisyCorrespondencesGiveASmallError) {
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0, 0.5);
  const Pose truth = pose_from_rotation_vector(Eigen::Vector3d(-0.4, 0.1, 0.2), Eigen::Vector3d(-30, 5, 12));
  const auto from = random_points(12, rng);
  std::vector<Eigen::Vector3d> to;
  for (const auto& p : from) to.push_back(truth * p + draw3(noise, rng));
  const PointRegistration r = register_points(from, to, {}, "test");
  EXPECT_NEAR(r.rms_mm, 0.5 * std::sqrt(3.0 * 9 / 12), 0.4);  // about the noise, fewer the 6 dof
  EXPECT_LT(rotation_angle_deg(r.transform * truth.inverse()), 1.0);
}

TEST(PointRegistration, DegenerateInputsAreBadInput) {
  const std::vector<Eigen::Vector3d> line = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {5, 5, 5}};
  EXPECT_THROW(register_points(line, line, {}, "lm.json"), InputError);
  const std::vector<Eigen::Vector3d> two = {{0, 0, 0}, {1, 0, 0}};
  EXPECT_THROW(register_points(two, two, {}, "lm.json"), InputError);
  const std::vector<Eigen::Vector3d> tri = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  EXPECT_THROW(register_points(tri, two, {}, "lm.json"), InputError);
  EXPECT_THROW(register_points(tri, tri, {1, -1, 1}, "lm.json"), InputError);
  EXPECT_THROW(register_points(tri, tri, {0, 0, 0}, "lm.json"), InputError);
  try {
    register_points(line, line, {}, "lm.json");
    ADD_FAILURE() << "collinear points accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("lm.json"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("collinear"), std::string::npos);
  }
}

TEST(Triangulation, RecoversPointsSeenByTwoOrThreeViews) {
  const CArmGeometry g;
  const std::vector<PinholeCamera> views = {c_arm_view(g, 0), c_arm_view(g, 90), c_arm_view(g, 45, 15)};
  std::mt19937 rng(9);
  for (const auto& x : random_points(10, rng)) {
    for (const size_t n : {size_t(2), size_t(3)}) {
      std::vector<PinholeCamera> cams(views.begin(), views.begin() + std::ptrdiff_t(n));
      std::vector<Eigen::Vector2d> px;
      for (const auto& c : cams) px.push_back(c.project(x));
      const Triangulation t = triangulate(cams, px, "test");
      EXPECT_LT((t.point - x).norm(), 1e-8);
      EXPECT_LT(t.rms_ray_distance_mm, 1e-8);
    }
  }
}

TEST(Triangulation, InconsistentPicksShowInTheRayDistance) {
  const CArmGeometry g;
  const std::vector<PinholeCamera> cams = {c_arm_view(g, 0), c_arm_view(g, 90)};
  const Eigen::Vector3d x(10, -20, 30);
  std::vector<Eigen::Vector2d> px = {cams[0].project(x), cams[1].project(x)};
  px[1].y() += 5;  // 5 pixels off along the image rows (the shared axis): the rays miss each other
  const Triangulation t = triangulate(cams, px, "test");
  EXPECT_GT(t.rms_ray_distance_mm, 0.5);
}

TEST(Triangulation, ParallelRaysAndSingleViewsAreBadInput) {
  const CArmGeometry g;
  const PinholeCamera a = c_arm_view(g, 0), b = c_arm_view(g, 0.2);  // 0.2 degrees apart
  EXPECT_THROW(triangulate({a, b}, {Eigen::Vector2d(256, 256), Eigen::Vector2d(256, 256)}, "pts.json"), InputError);
  EXPECT_THROW(triangulate({a}, {Eigen::Vector2d(256, 256)}, "pts.json"), InputError);
  EXPECT_THROW(triangulate({a, b}, {Eigen::Vector2d(256, 256)}, "pts.json"), InputError);
}

}  // namespace
}  // namespace fluoro
