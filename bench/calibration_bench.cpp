// The calibration pipeline's speed, with its accuracy as counters.
// Point tools: the Embree index build and closest-point queries (from scratch, and from the
// closest points before a small move) on a 100k-triangle mesh, a whole
// trimmed point-to-plane ICP of 5,000 noisy points with 10 % outliers starting 8 deg / 8 mm off
// (counters: surface TRE, rms, iterations), pivot calibration, and the Fitzpatrick-West
// prediction against a Monte-Carlo estimate (counter: measured / predicted TRE).
#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>
#include <random>

#include "datasets/point_tool_scenes.hpp"
#include "kernels/mesh/closest_point.hpp"
#include "pipelines/calibration/icp.hpp"
#include "pipelines/calibration/pivot_calibration.hpp"
#include "pipelines/calibration/target_registration_error.hpp"
#include "pipelines/registration/point_registration.hpp"

namespace fluoro {
namespace {

// make_lumpy_surface(159): 4 * 159 * 158 = 100,488 triangles.
const TriangleMesh& big_mesh() {
  static const TriangleMesh mesh = make_lumpy_surface(159);
  return mesh;
}

void BM_ClosestPointIndexBuild(benchmark::State& state) {
  for (auto _ : state) {
    MeshClosestPoint index(big_mesh(), "bench");
    benchmark::DoNotOptimize(index.triangle_count());
  }
  state.counters["triangles"] = double(big_mesh().triangles.size());
}
BENCHMARK(BM_ClosestPointIndexBuild)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ClosestPointQueries(benchmark::State& state) {
  const MeshClosestPoint index(big_mesh(), "bench");
  std::vector<Eigen::Vector3d> queries = sample_surface(big_mesh(), size_t(state.range(0)), 3);
  std::mt19937_64 rng(4);
  std::normal_distribution<double> gauss(0, 2.0);
  for (auto& q : queries) q += Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
  for (auto _ : state) benchmark::DoNotOptimize(index.closest(queries));
  state.SetItemsProcessed(int64_t(state.iterations()) * state.range(0));
}
BENCHMARK(BM_ClosestPointQueries)->Arg(5000)->Unit(benchmark::kMillisecond)->UseRealTime();

// The same queries searched from their closest points before a 0.5 mm move, as ICP does.
void BM_ClosestPointQueriesNear(benchmark::State& state) {
  const MeshClosestPoint index(big_mesh(), "bench");
  std::vector<Eigen::Vector3d> queries = sample_surface(big_mesh(), size_t(state.range(0)), 3);
  std::mt19937_64 rng(4);
  std::normal_distribution<double> gauss(0, 2.0);
  for (auto& q : queries) q += Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
  const std::vector<SurfacePoint> before = index.closest(queries);
  for (auto& q : queries) q += Eigen::Vector3d(0.3, -0.2, 0.35);
  for (auto _ : state) benchmark::DoNotOptimize(index.closest(queries, before));
  state.SetItemsProcessed(int64_t(state.iterations()) * state.range(0));
}
BENCHMARK(BM_ClosestPointQueriesNear)->Arg(5000)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_IcpPointToPlane(benchmark::State& state) {
  const MeshClosestPoint index(big_mesh(), "bench");
  const size_t n = size_t(state.range(0));
  const Pose truth = pose_from_rotation_vector(Eigen::Vector3d(0.1, 0.4, -0.2), Eigen::Vector3d(12, -40, 510));
  std::vector<Eigen::Vector3d> points = sample_surface(big_mesh(), n, 21);
  std::mt19937_64 rng(22);
  std::normal_distribution<double> gauss(0, 0.15);
  std::uniform_real_distribution<double> u(-1, 1);
  for (size_t i = 0; i < n; ++i) {
    points[i] += i < n / 10 ? (12.5 + 7.5 * u(rng)) * Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized()
                            : Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
    points[i] = truth * points[i];
  }
  const Pose start =
      truth * pose_from_rotation_vector(Eigen::Vector3d(-0.5, 0.2, 0.9).normalized() * 8 * std::numbers::pi / 180, {5, -4, 4.8});
  IcpResult r;
  for (auto _ : state) r = icp_point_to_plane(index, points, start);
  double tre = 0, start_error = 0;
  for (const auto& v : big_mesh().vertices) {
    tre += (r.T_world_model * v - truth * v).norm();
    start_error += (start * v - truth * v).norm();
  }
  state.counters["start_surface_error_mm"] = start_error / double(big_mesh().vertices.size());
  state.counters["ok"] = r.ok;
  state.counters["surface_tre_mm"] = tre / double(big_mesh().vertices.size());
  state.counters["rms_mm"] = r.rms_mm;
  state.counters["iterations"] = r.iterations;
  state.counters["inlier_fraction"] = r.inlier_fraction;
}
BENCHMARK(BM_IcpPointToPlane)->Arg(5000)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_PivotCalibration(benchmark::State& state) {
  const Eigen::Vector3d tip(3, -5, 152), pivot(100, 50, -1200);
  const auto poses = make_pivot_poses(tip, pivot, size_t(state.range(0)), 30, 0.2, 2);
  PivotCalibration r;
  for (auto _ : state) r = pivot_calibration(poses);
  state.counters["tip_error_mm"] = (r.tip_in_tool - tip).norm();
  state.counters["rms_mm"] = r.rms_mm;
  state.counters["rotation_spread_deg"] = r.rotation_spread_deg;
}
BENCHMARK(BM_PivotCalibration)->Arg(300)->Unit(benchmark::kMicrosecond);

// 2000 registrations of 6 fiducials with isotropic FLE (0.5 mm per axis) against the prediction
// at a target inside the fiducials and one 150 mm out.
void BM_FitzpatrickWestMonteCarlo(benchmark::State& state) {
  const std::vector<Eigen::Vector3d> moving = {{0, 0, 0},   {80, 10, 5},  {20, 90, -10},
                                               {-30, 40, 60}, {60, 70, 40}, {10, -20, 50}};
  const std::vector<Eigen::Vector3d> targets = {{25, 30, 25}, {150, 40, -30}};
  const Pose truth = pose_from_rotation_vector(Eigen::Vector3d(0.2, -1, 0.4).normalized() * 0.6, {40, -20, 300});
  std::vector<Eigen::Vector3d> fixed;
  for (const auto& m : moving) fixed.push_back(truth * m);
  const double sigma = 0.5;
  std::vector<double> ratio(targets.size());
  for (auto _ : state) {
    std::mt19937_64 rng(11);
    std::normal_distribution<double> gauss(0, sigma);
    std::vector<double> tre2(targets.size(), 0.0);
    for (int trial = 0; trial < 2000; ++trial) {
      std::vector<Eigen::Vector3d> noisy = moving;
      for (auto& p : noisy) p += Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
      const PointRegistration r = register_points(noisy, fixed, {}, "bench");
      for (size_t k = 0; k < targets.size(); ++k) tre2[k] += (r.transform * targets[k] - truth * targets[k]).squaredNorm();
    }
    for (size_t k = 0; k < targets.size(); ++k)
      ratio[k] = std::sqrt(tre2[k] / 2000) / predicted_tre_rms(moving, targets[k], sigma * std::sqrt(3.0));
  }
  state.counters["inner_target_measured_over_predicted"] = ratio[0];
  state.counters["outer_target_measured_over_predicted"] = ratio[1];
}
BENCHMARK(BM_FitzpatrickWestMonteCarlo)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace fluoro

BENCHMARK_MAIN();
