// The point tools against known truth: closest points against brute force, pivot calibration on
// generated pivoting poses, the Fitzpatrick-West TRE prediction against Monte-Carlo, and ICP of
// noisy points with outliers to a mesh and to a CT's bone surface.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

#include "engine/random_draws.hpp"
#include "datasets/phantom.hpp"
#include "datasets/point_tool_scenes.hpp"
#include "kernels/mesh/closest_point.hpp"
#include "pipelines/calibration/icp.hpp"
#include "pipelines/calibration/paired_point_registration.hpp"
#include "pipelines/calibration/pivot_calibration.hpp"
#include "pipelines/calibration/target_registration_error.hpp"
#include "pipelines/registration/bone_mesh.hpp"
#include "pipelines/registration/point_registration.hpp"

namespace fluoro {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

Pose make_pose(const Eigen::Vector3d& axis, double angle_deg, const Eigen::Vector3d& t) {
  return pose_from_rotation_vector(axis.normalized() * angle_deg * kDeg, t);
}

// Mean distance between where two poses put the mesh's vertices: the surface TRE.
double mean_surface_error(const Pose& a, const Pose& b, const std::vector<Eigen::Vector3d>& vertices) {
  double sum = 0;
  for (const auto& v : vertices) sum += (a * v - b * v).norm();
  return sum / double(vertices.size());
}

TEST(PointToolsClosestPoint, TriangleRegionsClosedForm) {
  const Eigen::Vector3d a(0, 0, 0), b(10, 0, 0), c(0, 10, 0);
  EXPECT_TRUE(closest_point_on_triangle({2, 3, 5}, a, b, c).isApprox(Eigen::Vector3d(2, 3, 0)));      // face
  EXPECT_TRUE(closest_point_on_triangle({-4, -2, 1}, a, b, c).isApprox(a));                           // vertex a
  EXPECT_TRUE(closest_point_on_triangle({14, -1, 0}, a, b, c).isApprox(b));                           // vertex b
  EXPECT_TRUE(closest_point_on_triangle({5, -3, 2}, a, b, c).isApprox(Eigen::Vector3d(5, 0, 0)));     // edge ab
  EXPECT_TRUE(closest_point_on_triangle({8, 8, -1}, a, b, c).isApprox(Eigen::Vector3d(5, 5, 0)));     // edge bc
  // A degenerate triangle (a segment) still gives the nearest point of the segment.
  EXPECT_TRUE(closest_point_on_triangle({5, 2, 0}, a, b, Eigen::Vector3d(5, 0, 0)).isApprox(Eigen::Vector3d(5, 0, 0)));
}

TEST(PointToolsClosestPoint, EmbreeQueryMatchesBruteForce) {
  const TriangleMesh mesh = make_lumpy_surface(16);
  const MeshClosestPoint index(mesh, "lumpy");
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-80, 80);
  std::vector<Eigen::Vector3d> queries;
  for (int i = 0; i < 300; ++i) {
    const Eigen::Vector3d r = draw3(u, rng);
    queries.emplace_back(r.x(), r.y(), 0.6 * r.z());
  }
  const std::vector<SurfacePoint> found = index.closest(queries);
  for (size_t i = 0; i < queries.size(); ++i) {
    double best = INFINITY;
    for (const auto& t : mesh.triangles)
      best = std::min(best, (closest_point_on_triangle(queries[i], mesh.vertices[size_t(t[0])], mesh.vertices[size_t(t[1])],
                                                       mesh.vertices[size_t(t[2])]) - queries[i]).norm());
    ASSERT_NEAR(found[i].distance, best, 1e-9) << "query " << i;
    EXPECT_NEAR((found[i].point - queries[i]).norm(), found[i].distance, 1e-12);
    EXPECT_NEAR(found[i].normal.norm(), 1.0, 1e-12);
  }
  // Searching from the closest points of slightly moved queries gives the same answers.
  std::vector<Eigen::Vector3d> moved = queries;
  for (auto& q : moved) q += Eigen::Vector3d(0.3, -0.2, 0.5);
  const std::vector<SurfacePoint> hinted = index.closest(moved, found);
  const std::vector<SurfacePoint> plain = index.closest(moved);
  for (size_t i = 0; i < moved.size(); ++i) ASSERT_NEAR(hinted[i].distance, plain[i].distance, 1e-12) << "query " << i;
}

TEST(PointToolsPivot, NoiseFreePosesGiveTheTipExactly) {
  const Eigen::Vector3d tip(3, -5, 152), pivot(100, 50, -1200);
  const auto poses = make_pivot_poses(tip, pivot, 20, 30, 0.0, 1);
  const PivotCalibration r = pivot_calibration(poses);
  ASSERT_TRUE(r.ok) << r.failure_reason;
  EXPECT_LT((r.tip_in_tool - tip).norm(), 1e-8);
  EXPECT_LT((r.pivot_in_tracker - pivot).norm(), 1e-8);
  EXPECT_LT(r.rms_mm, 1e-8);
}

TEST(PointToolsPivot, NoisyPosesWithinToleranceAndRmsMatchesNoise) {
  const Eigen::Vector3d tip(3, -5, 152), pivot(100, 50, -1200);
  const double sigma = 0.2;  // mm per axis on every pose's translation
  const size_t n = 300;
  const PivotCalibration r = pivot_calibration(make_pivot_poses(tip, pivot, n, 30, sigma, 2));
  ASSERT_TRUE(r.ok) << r.failure_reason;
  // Expected tip error ~ sigma / (sin(spread / 2) sqrt(n)) per axis, about 0.05 mm here.
  EXPECT_LT((r.tip_in_tool - tip).norm(), 0.25);
  EXPECT_LT((r.pivot_in_tracker - pivot).norm(), 0.25);
  // Residual 3D distances: E|e|^2 = 3 sigma^2 (1 - 6 / 3n) for 6 unknowns.
  EXPECT_NEAR(r.rms_mm, sigma * std::sqrt(3.0 * (1 - 2.0 / double(n))), 0.1 * sigma * std::sqrt(3.0));
  EXPECT_GT(r.rotation_spread_deg, 10);
}

TEST(PointToolsPivot, RotationAboutOneAxisOrTooFewPosesFail) {
  const Eigen::Vector3d tip(0, 0, 150), pivot(0, 0, -1000);
  std::vector<Pose> one_axis;
  for (int i = -5; i <= 5; ++i) {
    Pose T = make_pose({1, 0, 0}, 6.0 * i, Eigen::Vector3d::Zero());
    T.translation() = pivot - T.linear() * tip;
    one_axis.push_back(T);
  }
  const PivotCalibration a = pivot_calibration(one_axis);
  EXPECT_FALSE(a.ok);
  EXPECT_LT(a.rotation_spread_deg, 1e-3);
  EXPECT_NE(a.failure_reason.find("rotate too little"), std::string::npos) << a.failure_reason;
  const auto two = make_pivot_poses(tip, pivot, 2, 30, 0, 3);
  const PivotCalibration b = pivot_calibration(two);
  EXPECT_FALSE(b.ok);
  EXPECT_NE(b.failure_reason.find("too few poses"), std::string::npos) << b.failure_reason;
  // Small wobble (2 degrees) is below the default 10-degree spread: a failure, not a guess.
  EXPECT_FALSE(pivot_calibration(make_pivot_poses(tip, pivot, 50, 2, 0.1, 4)).ok);
}

TEST(PointToolsTre, FitzpatrickWestPredictionMatchesMonteCarlo) {
  // Six fiducials, asymmetric, 40-120 mm apart; targets near and far from their centroid.
  const std::vector<Eigen::Vector3d> moving = {{0, 0, 0},   {80, 10, 5},  {20, 90, -10},
                                               {-30, 40, 60}, {60, 70, 40}, {10, -20, 50}};
  const std::vector<Eigen::Vector3d> targets = {{25, 30, 25}, {150, 40, -30}, {-80, -60, 120}};
  const Pose truth = make_pose({0.2, -1, 0.4}, 35, {40, -20, 300});
  std::vector<Eigen::Vector3d> fixed;
  for (const auto& m : moving) fixed.push_back(truth * m);
  const double sigma = 0.5, fle_rms = sigma * std::sqrt(3.0);
  std::mt19937_64 rng(11);
  std::normal_distribution<double> gauss(0, sigma);
  const int trials = 2000;
  std::vector<double> tre2(targets.size(), 0.0);
  double fre2 = 0;
  for (int trial = 0; trial < trials; ++trial) {
    std::vector<Eigen::Vector3d> noisy = moving;
    for (auto& p : noisy) p += draw3(gauss, rng);
    const PointRegistration r = register_points(noisy, fixed, {}, "monte-carlo");
    fre2 += r.rms_mm * r.rms_mm;
    for (size_t k = 0; k < targets.size(); ++k) tre2[k] += (r.transform * targets[k] - truth * targets[k]).squaredNorm();
  }
  for (size_t k = 0; k < targets.size(); ++k) {
    const double measured = std::sqrt(tre2[k] / trials);
    const double predicted = predicted_tre_rms(moving, targets[k], fle_rms);
    EXPECT_NEAR(measured / predicted, 1.0, 0.10) << "target " << k << ": measured " << measured << ", predicted " << predicted;
  }
  // FRE^2 = (1 - 2/N) FLE^2 on average, and the FLE estimated from it is the true FLE.
  const double fre_rms = std::sqrt(fre2 / trials);
  EXPECT_NEAR(fle_from_fre(fre_rms, moving.size()) / fle_rms, 1.0, 0.05);
  // The far targets are predicted worse than the one inside the fiducials.
  EXPECT_GT(predicted_tre_rms(moving, targets[1], 1), predicted_tre_rms(moving, targets[0], 1));
}

// Weighted registration: fiducials localised with different errors (sigma_i), weighted 1 / sigma_i^2.
// The first-order prediction equals Fitzpatrick-West's closed form for equal weights, and matches a
// Monte-Carlo of the weighted Horn solution for unequal ones; the weights beat equal weights there.
TEST(PointToolsTre, WeightedPredictionMatchesFitzpatrickWestAndMonteCarlo) {
  const std::vector<Eigen::Vector3d> moving = {{0, 0, 0},   {80, 10, 5},  {20, 90, -10},
                                               {-30, 40, 60}, {60, 70, 40}, {10, -20, 50}};
  const std::vector<Eigen::Vector3d> targets = {{25, 30, 25}, {150, 40, -30}, {-80, -60, 120}};
  for (const auto& t : targets)
    EXPECT_NEAR(predicted_tre_rms_weighted(moving, std::vector<double>(6, 2.5), std::vector<double>(6, 0.7), t),
                predicted_tre_rms(moving, t, 0.7), 1e-9 * predicted_tre_rms(moving, t, 0.7));

  const std::vector<double> sigma = {0.2, 0.2, 1.2, 0.3, 1.0, 0.25};  // per axis, mm
  std::vector<double> weights, fle;
  for (double s : sigma) weights.push_back(1 / (s * s)), fle.push_back(s * std::sqrt(3.0));
  const Pose truth = make_pose({0.2, -1, 0.4}, 35, {40, -20, 300});
  std::vector<Eigen::Vector3d> fixed;
  for (const auto& m : moving) fixed.push_back(truth * m);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> gauss(0, 1);
  const int trials = 3000;
  std::vector<double> tre2(targets.size(), 0.0), tre2_equal(targets.size(), 0.0);
  for (int trial = 0; trial < trials; ++trial) {
    std::vector<Eigen::Vector3d> noisy = moving;
    for (size_t i = 0; i < noisy.size(); ++i)
      noisy[i] += sigma[i] * draw3(gauss, rng);
    const PointRegistration w = register_points(noisy, fixed, weights, "weighted");
    const PointRegistration e = register_points(noisy, fixed, {}, "equal");
    for (size_t k = 0; k < targets.size(); ++k) {
      tre2[k] += (w.transform * targets[k] - truth * targets[k]).squaredNorm();
      tre2_equal[k] += (e.transform * targets[k] - truth * targets[k]).squaredNorm();
    }
  }
  for (size_t k = 0; k < targets.size(); ++k) {
    const double measured = std::sqrt(tre2[k] / trials);
    const double predicted = predicted_tre_rms_weighted(moving, weights, fle, targets[k]);
    EXPECT_NEAR(measured / predicted, 1.0, 0.10) << "target " << k << ": measured " << measured << ", predicted " << predicted;
    EXPECT_LT(tre2[k], tre2_equal[k]) << "target " << k;  // the right weights help
  }
}

// The check of a given FLE against the residuals: with the true FLE it refutes about 0.1 % of
// registrations (its level; Wilson-Hilferty errs towards accepting), weighted or not; with a quarter
// of it, nearly all (96 % in theory with 4 points); and its FLE from the residuals is the FRE's estimate when unweighted.
TEST(PointToolsTre, AGivenFleIsCheckedAgainstTheResiduals) {
  const std::vector<Eigen::Vector3d> moving = {{0, 0, 0}, {80, 10, 5}, {20, 90, -10}, {-30, 40, 60}};
  const Pose truth = make_pose({0.2, -1, 0.4}, 35, {40, -20, 300});
  const std::vector<double> sigma = {0.2, 0.6, 0.3, 0.4};  // per axis, mm
  std::vector<double> weights;
  double mean_fle2 = 0;
  for (double s : sigma) weights.push_back(1 / (s * s)), mean_fle2 += 3 * s * s / double(sigma.size());
  std::mt19937_64 rng(3);
  std::normal_distribution<double> gauss(0, 1);
  const int trials = 4000;
  int refuted_equal = 0, refuted_weighted = 0, refuted_small = 0;
  for (int trial = 0; trial < trials; ++trial) {
    std::vector<Eigen::Vector3d> fixed, fixed_unequal;
    for (size_t i = 0; i < moving.size(); ++i) {
      fixed.push_back(truth * moving[i] + 0.4 * draw3(gauss, rng));
      fixed_unequal.push_back(truth * moving[i] + sigma[i] * draw3(gauss, rng));
    }
    const double fle = 0.4 * std::sqrt(3.0);
    const PairedRegistration a = register_paired_points(fixed, moving, {}, fle);
    ASSERT_TRUE(a.ok && a.fle_check);
    refuted_equal += !a.fle_check->consistent;
    refuted_small += !register_paired_points(fixed, moving, {}, fle / 4).fle_check->consistent;
    if (trial == 0)
      EXPECT_NEAR(a.fle_check->fle_from_residuals_mm, fle_from_fre(a.fre_rms_mm, moving.size()), 1e-9);
    const PairedRegistration w = register_paired_points(fixed_unequal, moving, {}, std::sqrt(mean_fle2), weights);
    refuted_weighted += !w.fle_check->consistent;
  }
  EXPECT_LE(refuted_equal, 12) << "of " << trials;  // 0.1 % is 4; a miscalibrated test gives far more
  EXPECT_LE(refuted_weighted, 12) << "of " << trials;
  EXPECT_GT(refuted_small, trials * 9 / 10);
  // Estimated from the residuals, there is nothing to check.
  EXPECT_FALSE(register_paired_points({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {},
                                      std::nullopt).fle_check);
}

TEST(PointToolsTre, PairedRegistrationRecoversPoseAndRejectsCollinearPoints) {
  const std::vector<Eigen::Vector3d> moving = {{0, 0, 0}, {80, 10, 5}, {20, 90, -10}, {-30, 40, 60}};
  const Pose truth = make_pose({1, 1, 0}, -50, {5, 6, 7});
  std::vector<Eigen::Vector3d> fixed;
  for (const auto& m : moving) fixed.push_back(truth * m);
  const PairedRegistration r = register_paired_points(fixed, moving, {{10, 10, 10}}, 0.4);
  ASSERT_TRUE(r.ok) << r.failure_reason;
  EXPECT_TRUE(r.T_fixed_moving.matrix().isApprox(truth.matrix(), 1e-9));
  EXPECT_LT(r.fre_rms_mm, 1e-9);
  ASSERT_EQ(r.predicted_tre_rms_mm.size(), 1u);
  EXPECT_NEAR(r.predicted_tre_rms_mm[0], predicted_tre_rms(moving, {10, 10, 10}, 0.4), 1e-12);
  EXPECT_FALSE(r.fle_estimated);

  const std::vector<Eigen::Vector3d> line = {{0, 0, 0}, {10, 10, 10}, {20, 20, 20.001}, {35, 35, 35}};
  const PairedRegistration bad = register_paired_points(line, line, {}, std::nullopt);
  EXPECT_FALSE(bad.ok);
  EXPECT_NE(bad.failure_reason.find("collinear"), std::string::npos) << bad.failure_reason;
  EXPECT_FALSE(register_paired_points({{0, 0, 0}, {1, 0, 0}}, {{0, 0, 0}, {1, 0, 0}}, {}, std::nullopt).ok);
}

// Points on the surface at a known pose, with noise and 10 % outliers.
std::vector<Eigen::Vector3d> noisy_cloud(const TriangleMesh& mesh, const Pose& T_world_model, size_t n, double sigma,
                                         double outlier_fraction, uint64_t seed) {
  std::vector<Eigen::Vector3d> points = sample_surface(mesh, n, seed);
  std::mt19937_64 rng(seed + 1);
  std::normal_distribution<double> gauss(0, sigma);
  std::uniform_real_distribution<double> u(-1, 1);
  for (size_t i = 0; i < points.size(); ++i) {
    if (double(i) < outlier_fraction * double(n)) {
      // Off the surface by 5 to 20 mm in a random direction (a slipped pointer, soft tissue).
      const Eigen::Vector3d dir = draw3(u, rng).normalized();
      points[i] += (12.5 + 7.5 * u(rng)) * dir;
    } else {
      points[i] += draw3(gauss, rng);
    }
    points[i] = T_world_model * points[i];
  }
  return points;
}

TEST(PointToolsIcp, RecoversPoseOfAsymmetricMeshWithNoiseAndOutliers) {
  const TriangleMesh mesh = make_lumpy_surface(40);
  const MeshClosestPoint index(mesh, "lumpy");
  const Pose truth = make_pose({0.3, 0.8, -0.2}, 25, {12, -40, 510});
  const auto points = noisy_cloud(mesh, truth, 1500, 0.15, 0.10, 21);
  // Start 8 degrees and 8 mm off.
  const Pose start = truth * make_pose({-0.5, 0.2, 0.9}, 8, Eigen::Vector3d(5, -4, 4.8));
  EXPECT_GT(mean_surface_error(start, truth, mesh.vertices), 8.0);
  const IcpResult r = icp_point_to_plane(index, points, start);
  ASSERT_TRUE(r.ok) << r.failure_reason;
  EXPECT_LT(mean_surface_error(r.T_world_model, truth, mesh.vertices), 0.1);
  EXPECT_LT(rotation_angle_deg(r.T_world_model.inverse() * truth), 0.1);
  // Kept pairs: 90 % nearest, i.e. the inliers' normal noise (0.15 mm rms), trimmed a little.
  EXPECT_GT(r.rms_mm, 0.05);
  EXPECT_LT(r.rms_mm, 0.2);
  EXPECT_NEAR(r.inlier_fraction, 0.9, 0.03);
  EXPECT_GT(r.iterations, 1);
}

TEST(PointToolsIcp, FifteenNoisyPointsConverge) {
  // The seed's cloud-of-points experiment: 15 digitised points, one of them an outlier. With so
  // few, a point at the trimming boundary may swap in and out and closest points sit on edges;
  // the iteration must still converge, every time. From 5 deg / 5 mm off, 15 points on a smooth
  // shape have local minima: most runs, not all, recover the pose (measured: 9 of 10 within 1.2 mm).
  const TriangleMesh mesh = make_lumpy_surface(40);
  const MeshClosestPoint index(mesh, "lumpy");
  const Pose truth = make_pose({0.3, 0.8, -0.2}, 25, {12, -40, 510});
  int recovered = 0;
  for (uint64_t seed = 30; seed < 40; ++seed) {
    const auto points = noisy_cloud(mesh, truth, 15, 0.3, 0.05, seed);  // one outlier (point 0)
    const Pose start = truth * make_pose({0.5, 0.2, -0.9}, 5, Eigen::Vector3d(3, -2, 2));
    const IcpResult r = icp_point_to_plane(index, points, start);
    ASSERT_TRUE(r.ok) << "seed " << seed << ": " << r.failure_reason;
    EXPECT_LT(r.iterations, 60) << "seed " << seed;
    recovered += mean_surface_error(r.T_world_model, truth, mesh.vertices) < 1.5 ? 1 : 0;
  }
  EXPECT_GE(recovered, 8);
}

TEST(PointToolsIcp, SeedContactExperimentLandmarksThenFifteenPoints) {
  // The seed's contact experiment: 3 landmarks touched with a 2.5 mm depth error give the initial
  // registration, then a cloud of 15 surface points refines it. The refinement must beat the
  // landmarks on the whole (median over 10 trials) and bring the pose within a millimetre.
  const TriangleMesh mesh = make_lumpy_surface(40);
  const MeshClosestPoint index(mesh, "lumpy");
  const Pose truth = make_pose({0.3, 0.8, -0.2}, 25, {12, -40, 510});
  const std::vector<Eigen::Vector3d> landmarks = {mesh.vertices[100], mesh.vertices[1500], mesh.vertices[2900]};
  std::vector<double> before, after;
  std::mt19937_64 rng(77);
  std::uniform_real_distribution<double> u(-1, 1);
  for (uint64_t trial = 0; trial < 10; ++trial) {
    std::vector<Eigen::Vector3d> touched;
    for (const auto& l : landmarks) {
      // The pointer stops 2.5 mm off in depth, along a direction of its own.
      touched.push_back(truth * l + 2.5 * draw3(u, rng).normalized());
    }
    const PairedRegistration initial = register_paired_points(touched, landmarks, {}, std::nullopt);
    ASSERT_TRUE(initial.ok) << initial.failure_reason;
    const auto points = noisy_cloud(mesh, truth, 15, 0.25, 0.0, 200 + trial);
    const IcpResult r = icp_point_to_plane(index, points, initial.T_fixed_moving);
    ASSERT_TRUE(r.ok) << r.failure_reason;
    before.push_back(mean_surface_error(initial.T_fixed_moving, truth, mesh.vertices));
    after.push_back(mean_surface_error(r.T_world_model, truth, mesh.vertices));
  }
  std::sort(before.begin(), before.end());
  std::sort(after.begin(), after.end());
  std::printf("landmarks median %.2f mm, after 15-point ICP median %.2f mm (worst %.2f)\n", before[5], after[5], after[9]);
  EXPECT_LT(after[5], before[5]);
  EXPECT_LT(after[5], 1.0);
}

TEST(PointToolsIcp, SphereDoesNotConstrainRotation) {
  // A sphere's rotation is free: a failure with a reason, not an arbitrary pose.
  TriangleMesh sphere = make_lumpy_surface(60);
  for (auto& v : sphere.vertices) v = 30 * v.normalized();
  const MeshClosestPoint index(sphere, "sphere");
  const IcpResult r = icp_point_to_plane(index, sample_surface(sphere, 400, 3), Pose::Identity());
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.failure_reason.find("does not constrain"), std::string::npos) << r.failure_reason;
  EXPECT_FALSE(icp_point_to_plane(index, {{1, 2, 3}, {4, 5, 6}}, Pose::Identity()).ok);  // too few points
}

TEST(PointToolsIcp, RegistersPointsToCtBoneSurface) {
  // The truth surface from a finer CT of the same phantom than the one registered to.
  PhantomParams fine_params;
  fine_params.size = 128;
  BoneMeshParams mesh_params;
  mesh_params.max_voxel_mm = 2.0;
  mesh_params.max_triangles = 400000;
  const BoneMesh fine = bone_mesh_from_iso(make_phantom(fine_params).hu, 250, mesh_params, "fine phantom");
  const TriangleMesh truth_surface{fine.vertices, fine.triangles};
  PhantomParams coarse_params;
  coarse_params.size = 96;
  const BoneMesh coarse = bone_mesh_from_iso(make_phantom(coarse_params).hu, 250, mesh_params, "coarse phantom");
  const MeshClosestPoint index(TriangleMesh{coarse.vertices, coarse.triangles}, "coarse phantom");

  const Pose truth = make_pose({1, 0.2, 0.1}, 90, {0, 20, 700});
  const auto points = noisy_cloud(truth_surface, truth, 800, 0.2, 0.10, 5);
  const Pose start = truth * make_pose({0.4, -0.8, 0.3}, 6, Eigen::Vector3d(-6, 3, 2));
  const IcpResult r = icp_point_to_plane(index, points, start);
  ASSERT_TRUE(r.ok) << r.failure_reason;
  // The two marching-cubes surfaces differ by a fraction of a voxel; the pose much less than that.
  EXPECT_LT(mean_surface_error(r.T_world_model, truth, fine.vertices), 0.5);
  EXPECT_LT(r.rms_mm, 0.8);
}

}  // namespace
}  // namespace fluoro
