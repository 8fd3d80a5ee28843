// The fine registration step: the batched downhill simplex and quasi-Newton on functions with
// known minima, and
// gradient projection registration of a phantom from a 5 mm / 3 degree start on DRR-simulated
// views with known poses.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>

#include "datasets/c_arm.hpp"
#include "datasets/phantom.hpp"
#include "engine/attenuation.hpp"
#include "engine/backend.hpp"
#include "engine/xray.hpp"
#include "kernels/backend_registry.hpp"
#include "pipelines/registration/edge_pixels.hpp"
#include "pipelines/registration/error_metrics.hpp"
#include "pipelines/registration/gpr_registration.hpp"
#include "pipelines/registration/quasi_newton.hpp"
#include "pipelines/registration/simplex.hpp"

namespace fluoro {
namespace {

BatchObjective batch(std::function<double(const Eigen::VectorXd&)> f, int* calls) {
  return [f, calls](const std::vector<Eigen::VectorXd>& xs) {
    ++*calls;
    std::vector<double> v;
    for (const auto& x : xs) v.push_back(f(x));
    return v;
  };
}

TEST(Simplex, FindsTheMinimumOfAQuadraticAndOfRosenbrock) {
  int calls = 0;
  const Eigen::VectorXd target = (Eigen::VectorXd(6) << 1, -2, 3, 0.5, -0.5, 4).finished();
  const auto quadratic = [&](const Eigen::VectorXd& x) {
    return (x - target).cwiseProduct(Eigen::VectorXd::LinSpaced(6, 1, 6)).squaredNorm();
  };
  SimplexOptions o;
  o.max_iterations = 5000;
  o.x_tolerance = 1e-6;
  o.f_tolerance = 1e-12;
  const SimplexResult q = minimize_simplex(batch(quadratic, &calls), Eigen::VectorXd::Zero(6),
                                           Eigen::VectorXd::Ones(6), o);
  EXPECT_TRUE(q.converged);
  EXPECT_LT((q.x - target).norm(), 1e-4);
  // Speculative steps: the same iterates, one call per step (plus shrinks and the start), about
  // twice the evaluations of on-demand steps.
  int speculative_calls = 0;
  SimplexOptions so = o;
  so.speculative = true;
  const SimplexResult s = minimize_simplex(batch(quadratic, &speculative_calls), Eigen::VectorXd::Zero(6),
                                           Eigen::VectorXd::Ones(6), so);
  EXPECT_EQ(s.iterations, q.iterations);
  EXPECT_EQ((s.x - q.x).norm(), 0.0);
  EXPECT_LT(speculative_calls, s.evaluations / 2);
  EXPECT_LT(double(q.evaluations), 0.6 * s.evaluations);

  const auto rosenbrock = [](const Eigen::VectorXd& x) {
    return 100 * std::pow(x[1] - x[0] * x[0], 2) + std::pow(1 - x[0], 2);
  };
  const SimplexResult r = minimize_simplex(batch(rosenbrock, &calls), Eigen::Vector2d(-1.2, 1.0),
                                           Eigen::Vector2d(0.5, 0.5), o);
  EXPECT_TRUE(r.converged);
  EXPECT_LT((r.x - Eigen::Vector2d(1, 1)).norm(), 1e-3);
}

TEST(QuasiNewton, FindsTheMinimaOfACoupledQuadraticAndOfRosenbrockInFewBatches) {
  // A quadratic with strong couplings between the parameters (like rotations and translations of
  // a pose about a point off the bone's centre) and axes scaled 1 to 6.
  const Eigen::VectorXd target = (Eigen::VectorXd(6) << 1, -2, 3, 0.5, -0.5, 4).finished();
  Eigen::MatrixXd a = Eigen::MatrixXd::Identity(6, 6);
  for (int i = 0; i < 5; ++i) a(i, i + 1) = 0.8;
  a = a * Eigen::VectorXd::LinSpaced(6, 1, 6).asDiagonal();
  const auto quadratic = [&](const Eigen::VectorXd& x) { return (a * (x - target)).squaredNorm(); };
  int calls = 0;
  QuasiNewtonOptions o;
  o.max_iterations = 100;
  o.f_tolerance = 1e-12;
  o.x_tolerance = 1e-6;
  const QuasiNewtonResult q = minimize_quasi_newton(batch(quadratic, &calls), Eigen::VectorXd::Zero(6),
                                                    Eigen::VectorXd::Ones(6), o);
  EXPECT_TRUE(q.converged);
  EXPECT_LT((q.x - target).norm(), 1e-4);
  EXPECT_EQ(calls, q.batches);
  EXPECT_EQ(q.batches, 2 * q.iterations);
  // Central differences are exact on a quadratic, so BFGS learns the couplings: far fewer
  // evaluations than the simplex needs for the same precision.
  int simplex_calls = 0;
  SimplexOptions so;
  so.max_iterations = 5000;
  so.f_tolerance = 1e-12;
  so.x_tolerance = 1e-6;
  const SimplexResult s = minimize_simplex(batch(quadratic, &simplex_calls), Eigen::VectorXd::Zero(6),
                                           Eigen::VectorXd::Ones(6), so);
  EXPECT_LT((s.x - target).norm(), 1e-4);
  EXPECT_LT(q.evaluations, s.evaluations / 2) << q.evaluations << " against the simplex's " << s.evaluations;

  const auto rosenbrock = [](const Eigen::VectorXd& x) {
    return 100 * std::pow(x[1] - x[0] * x[0], 2) + std::pow(1 - x[0], 2);
  };
  o.max_iterations = 200;
  const QuasiNewtonResult r = minimize_quasi_newton(batch(rosenbrock, &calls), Eigen::Vector2d(-1.2, 1.0),
                                                    Eigen::Vector2d(0.5, 0.5), o);
  EXPECT_TRUE(r.converged);
  EXPECT_LT((r.x - Eigen::Vector2d(1, 1)).norm(), 1e-3);

  // Never uphill: from the minimum of a function with a kink there (no gradient to follow), the
  // start comes back.
  const auto kink = [](const Eigen::VectorXd& x) { return x.cwiseAbs().sum(); };
  const QuasiNewtonResult k = minimize_quasi_newton(batch(kink, &calls), Eigen::VectorXd::Zero(3),
                                                    Eigen::VectorXd::Ones(3), o);
  EXPECT_TRUE(k.converged);
  EXPECT_EQ(k.value, 0.0);
  EXPECT_EQ(k.x.norm(), 0.0);
}

TEST(GprRegistration, ConvergesFromFiveMillimetresBelowHalfAMillimetre) {
  auto backend = make_backend("cpu");
  PhantomParams pp;
  pp.kind = PhantomKind::femur;
  pp.size = 128;
  const Phantom phantom = make_phantom(pp);
  const auto mu = backend->upload(hu_to_attenuation(phantom.hu));
  const auto gradient = backend->gradient_field(*backend->upload(hu_to_attenuation(phantom.hu, {0.02, 200.0})), {1.0, 0.0});

  CArmGeometry g;
  g.pixels = 384;
  g.pixel_mm = 0.8;
  const std::vector<PinholeCamera> views = {c_arm_view(g, 0), c_arm_view(g, 60), c_arm_view(g, 100, 15)};
  const Pose truth = pose_from_rotation_vector(Eigen::Vector3d(0.04, -0.02, 0.08), Eigen::Vector3d(3, -2, 4));
  const auto drrs = backend->drr(*mu, std::span(&truth, 1), views, DrrParams{0.5, {}});
  std::vector<EdgePixels> edges;
  EdgeDetectionParams ep;
  ep.max_pixels = 2500;
  for (const Image& d : drrs)
    edges.push_back(detect_edge_pixels(drr_to_xray(d, display_mapping(d, 1000.0)), XrayPolarity::log_domain, ep, "drr"));

  const auto surface = surface_points(phantom.hu, 700, 2000);
  const Eigen::Vector3d centre = phantom.hu.geometry.physical_centre();
  // 5 mm and 3 degrees off, in a few directions.
  const Eigen::Vector3d shifts[] = {{5, 0, 0}, {0, -3, 4}, {-2.9, 2.9, -2.9}};
  const Eigen::Vector3d axes[] = {{0, 0, 1}, {1, 0, 0}, {1, 1, -1}};
  for (int trial = 0; trial < 3; ++trial) {
    const Pose delta = pose_from_rotation_vector(axes[trial].normalized() * (3.0 * std::numbers::pi / 180.0), shifts[trial]);
    Pose start = truth;
    start.linear() = delta.linear() * truth.linear();
    start.translation() = truth.translation() + shifts[trial];
    const double start_tre = registration_errors(start, truth, surface, {}, views).surface_tre_mean_mm;
    const auto t0 = std::chrono::steady_clock::now();
    const GprRegistrationResult r = register_gpr(*backend, *gradient, views, edges, start, centre);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const RegistrationErrors e = registration_errors(r.pose, truth, surface, {}, views);
    EXPECT_GT(start_tre, 4.0) << trial;
    EXPECT_LT(e.surface_tre_mean_mm, 0.5) << "trial " << trial << ": from " << start_tre << " mm, " << r.evaluations
                                          << " evaluations, " << seconds << " s";
    EXPECT_GT(r.score, r.initial_score);
    RecordProperty("trial" + std::to_string(trial) + "_final_tre_mm", std::to_string(e.surface_tre_mean_mm));
    std::printf("trial %d: surface TRE %.2f -> %.3f mm (max %.3f), %d evaluations, %.2f s\n", trial, start_tre,
                e.surface_tre_mean_mm, e.surface_tre_max_mm, r.evaluations, seconds);
  }
  // The batched quasi-Newton (selectable per stage) from the first start: as close.
  const Pose delta = pose_from_rotation_vector(axes[0].normalized() * (3.0 * std::numbers::pi / 180.0), shifts[0]);
  Pose start = truth;
  start.linear() = delta.linear() * truth.linear();
  start.translation() = truth.translation() + shifts[0];
  GprRegistrationOptions qn;
  qn.optimiser = FineOptimiser::quasi_newton;
  const GprRegistrationResult q = register_gpr(*backend, *gradient, views, edges, start, centre, qn);
  const RegistrationErrors e = registration_errors(q.pose, truth, surface, {}, views);
  EXPECT_LT(e.surface_tre_mean_mm, 0.5) << q.evaluations << " evaluations";
  EXPECT_GT(q.score, q.initial_score);
  std::printf("quasi-Newton, trial 0: %.3f mm (max %.3f), %d evaluations\n", e.surface_tre_mean_mm, e.surface_tre_max_mm,
              q.evaluations);
}

}  // namespace
}  // namespace fluoro
