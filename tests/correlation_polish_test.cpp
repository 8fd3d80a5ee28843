// The correlation polish (correlation_polish.hpp): its parabola step against closed forms, and its
// steps on correlations that are known functions of the pose.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "pipelines/registration/correlation_polish.hpp"
#include "pipelines/registration/peak_sharpness.hpp"

namespace fluoro {
namespace {

using Params = Eigen::Matrix<double, 6, 1>;

// A measurement whose every view correlates f at the pose and f at its displacements.
PeakSharpness measurement_of(const std::function<double(const Params&)>& f, const Params& at, int views = 3) {
  PeakSharpness p;
  ViewSharpness v;
  v.correlation = f(at);
  for (int a = 0; a < 6; ++a)
    for (double sign : {-1.0, 1.0}) {
      Params x = at;
      x[a] += sign * (a < 3 ? p.options.rotation_deg : p.options.translation_mm);
      v.measured.push_back(f(x));
    }
  p.views.assign(views, v);
  p.evaluations = 13;
  return p;
}

TEST(CorrelationPolish, TheStepPutsEveryAxisAtItsParabolasPeak) {
  // f = 0.5 - 0.004 sum (x - x0)^2: a parabola on every axis, peaks within half a displacement.
  const Params x0 = (Params() << 0.4, -0.9, 1.2, -0.3, 0.7, -1.4).finished();
  const auto f = [&](const Params& x) { return 0.5 - 0.004 * (x - x0).squaredNorm(); };
  const PeakSharpness p = measurement_of(f, Params::Zero());
  const std::vector<double> mean = mean_displaced_correlations(p);
  ASSERT_EQ(mean.size(), 13u);
  EXPECT_NEAR(mean[0], f(Params::Zero()), 1e-12);
  for (int a = 0; a < 6; ++a) EXPECT_NEAR(parabola_peak_step(mean, 3, 3, 1.0)[a], x0[a], 1e-9) << "axis " << a;
  // Relaxed: 4/3 of the way, but never beyond half a displacement (1.5 degrees or mm).
  const Params relaxed = parabola_peak_step(mean, 3, 3, 4.0 / 3.0);
  for (int a = 0; a < 6; ++a) EXPECT_NEAR(relaxed[a], std::clamp(4.0 / 3.0 * x0[a], -1.5, 1.5), 1e-9) << "axis " << a;
}

TEST(CorrelationPolish, OnAPeakLikeTheAbsoluteValueAParabolaFindsHalfTheWay) {
  // f = 0.5 - 0.01 |x - x0| along one axis: through -d, 0, +d the parabola peaks at d x0 / 2 (d - x0),
  // about half of x0: hence the relaxation (correlation_polish.hpp).
  const double x0 = 0.3, d = 3.0;
  const auto f = [&](const Params& x) { return 0.5 - 0.01 * std::abs(x[3] - x0) - 0.01 * x.head<3>().norm(); };
  const std::vector<double> mean = mean_displaced_correlations(measurement_of(f, Params::Zero()));
  EXPECT_NEAR(parabola_peak_step(mean, d, d, 1.0)[3], d * x0 / (2 * (d - x0)), 1e-9);
  EXPECT_NEAR(parabola_peak_step(mean, d, d, 1.0)[4], 0.0, 1e-12) << "a flat axis does not move";
}

TEST(CorrelationPolish, AnAxisThatDoesNotDropMovesHalfADisplacementUphill) {
  const auto f = [](const Params& x) { return 0.5 + 0.01 * x[1] - 0.001 * x.squaredNorm() + 0.001 * x[1] * x[1]; };
  const Params step = parabola_peak_step(mean_displaced_correlations(measurement_of(f, Params::Zero())), 3, 3, 4.0 / 3.0);
  EXPECT_DOUBLE_EQ(step[1], 1.5);
  // A valley (the correlation rises both ways, more on one side): half a displacement that way.
  const auto valley = [](const Params& x) { return 0.5 + 0.001 * x[2] * x[2] - 0.01 * x[2]; };
  EXPECT_DOUBLE_EQ(parabola_peak_step(mean_displaced_correlations(measurement_of(valley, Params::Zero())), 3, 3, 1.0)[2], -1.5);
  PeakSharpness missing = measurement_of(f, Params::Zero());
  missing.views[1].measured.pop_back();
  EXPECT_TRUE(mean_displaced_correlations(missing).empty());
  EXPECT_EQ(parabola_peak_step(mean_displaced_correlations(missing), 3, 3, 1.0), Params::Zero())
      << "a view without its displacements: no step";
}

// The pose's parameters (apply_pose_parameters': degrees about `centre`, then mm) from `reference`.
Params parameters_of(const Pose& pose, const Pose& reference, const Eigen::Vector3d& centre) {
  const Pose delta = pose * reference.inverse();
  const Eigen::AngleAxisd r(delta.linear());
  Params x;
  x.head<3>() = r.axis() * r.angle() * 180.0 / std::numbers::pi;
  x.tail<3>() = delta.translation() - centre + delta.linear() * centre;
  return x;
}

// A correlation known as a function of the pose's parameters from `start` about a fixed centre:
// the polish's measurement, counting the confidence checks (the options' default displacements)
// and the stencils (the polish's).
struct KnownCorrelation {
  std::function<double(const Params&)> f;
  Pose start;
  Eigen::Vector3d centre_ct, centre;
  int measured = 0, stencils = 0;
  PeakSharpnessOptions stencil_options;  // the last stencil's
  MeasurePeak measure() {
    return [this](const Pose& pose, const PeakSharpnessOptions& o) {
      const bool check = o.rotation_deg == PeakSharpnessOptions{}.rotation_deg;
      ++(check ? measured : stencils);
      if (!check) stencil_options = o;
      PeakSharpness p;
      p.options = o;
      ViewSharpness v;
      v.correlation = f(parameters_of(pose, start, centre));
      for (const Pose& d : displaced_poses(pose, pose * centre_ct, o)) v.measured.push_back(f(parameters_of(d, start, centre)));
      p.views.assign(2, v);
      p.evaluations = 7;
      return p;
    };
  }
  PeakSharpness check(const Pose& pose) { return measure()(pose, PeakSharpnessOptions{}); }
};

TEST(CorrelationPolish, StepsToTheOptimumOfAPeakedCorrelation) {
  // Peaked like |x| on every axis around a pose 0.5 degrees and 0.6 mm from the start, with a
  // coupling between a rotation and a translation that a diagonal step does not see.
  KnownCorrelation k;
  k.start = pose_from_rotation_vector(Eigen::Vector3d(0.1, -0.2, 0.3), Eigen::Vector3d(10, -20, 300));
  k.centre_ct = Eigen::Vector3d(5, 6, 7);
  k.centre = k.start * k.centre_ct;
  const Params optimum = (Params() << 0.5, -0.3, 0.2, 0.6, -0.4, 0.3).finished();
  k.f = [&](const Params& x) {
    const Params e = x - optimum;
    return 0.6 - 0.01 * e.cwiseAbs().sum() - 0.002 * std::abs(e[0] + e[4]);
  };
  CorrelationPolishOptions o;
  o.max_steps = 8;
  const CorrelationPolishResult r =
      polish_by_correlation(k.measure(), k.start, k.check(k.start), k.centre_ct, o);
  const Params reached = parameters_of(r.pose, k.start, k.centre);
  EXPECT_LT((reached - optimum).cwiseAbs().maxCoeff(), 0.05) << reached.transpose();
  EXPECT_GT(r.correlation, r.initial_correlation);
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(k.stencils, r.steps) << "one stencil per step";
  EXPECT_EQ(k.measured, 2) << "the start's check, and the result's";
  EXPECT_EQ(r.evaluations, 7 * r.steps + 7);
  // The stencils: the check's measurement (its translations warped) at the polish's displacement.
  EXPECT_EQ(k.stencil_options.rotation_deg, o.displacement);
  EXPECT_EQ(k.stencil_options.translation_mm, o.displacement);
  EXPECT_TRUE(k.stencil_options.translations_by_warp);
  EXPECT_NEAR(r.at_pose.views[0].correlation, r.correlation, 1e-12) << "the result's own measurement";
}

TEST(CorrelationPolish, TheLastAllowedStepIsRenderedAsTheConfidenceCheck) {
  // Far from a |x|-like peak, three steps do not converge; the third pose's stencil would give a
  // step never taken, so it is rendered as the check instead.
  KnownCorrelation k;
  k.start = Pose::Identity();
  k.centre_ct = k.centre = Eigen::Vector3d::Zero();
  k.f = [](const Params& x) { return 0.6 - 0.01 * std::abs(x[4] - 1.4) - 0.01 * x.head<3>().cwiseAbs().sum(); };
  const CorrelationPolishResult r =
      polish_by_correlation(k.measure(), k.start, k.check(k.start), k.centre_ct, CorrelationPolishOptions{});
  EXPECT_EQ(r.steps, 3);
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(k.stencils, 2) << "stencils for the first two steps' poses only";
  EXPECT_EQ(k.measured, 2) << "the start's check and the third pose's, which is the result's";
  EXPECT_EQ(r.evaluations, 3 * 7);
  const Params reached = parameters_of(r.pose, k.start, k.centre);
  EXPECT_GT(reached[4], 1.0);
  EXPECT_NEAR(r.at_pose.views[0].correlation, r.correlation, 1e-12);
  EXPECT_NEAR(r.correlation, k.f(reached), 1e-12);
}

TEST(CorrelationPolish, AStepThatLandsWorseIsRefusedAndTheBestPoseIsMeasured) {
  // The first step (from the +-3 stencil) reaches 0.5 mm of a peak at 0.6; the second (from the
  // +-1 stencil there) would go to about 0.556, into a dip.
  KnownCorrelation k;
  k.start = Pose::Identity();
  k.centre_ct = k.centre = Eigen::Vector3d::Zero();
  k.f = [](const Params& x) {
    if (x[3] > 0.54 && x[3] < 0.58) return 0.3;
    return 0.5 - 0.01 * std::abs(x[3] - 0.6) - 0.01 * x.head<3>().cwiseAbs().sum();
  };
  const CorrelationPolishResult r =
      polish_by_correlation(k.measure(), k.start, k.check(k.start), k.centre_ct, CorrelationPolishOptions{});
  EXPECT_EQ(r.steps, 2);
  EXPECT_NEAR(parameters_of(r.pose, k.start, k.centre)[3], 0.5, 1e-9);
  EXPECT_EQ(k.stencils, 2);
  EXPECT_EQ(k.measured, 2) << "the start's check, and the best pose's, measured again";
  EXPECT_NEAR(r.at_pose.views[0].correlation, k.f(parameters_of(r.pose, k.start, k.centre)), 1e-12);
}

TEST(CorrelationPolish, NeverEndsWorseThanItStarted) {
  // The displaced correlations point to a peak at +1 mm along x, but the step lands in a dip.
  KnownCorrelation k;
  k.start = Pose::Identity();
  k.centre_ct = k.centre = Eigen::Vector3d::Zero();
  k.f = [](const Params& x) {
    if (x[3] > 0.5 && x[3] < 1.3) return 0.3;
    return 0.5 - 0.01 * std::abs(x[3] - 1.0) - 0.01 * x.head<3>().cwiseAbs().sum();
  };
  const PeakSharpness at_start = k.check(k.start);
  const CorrelationPolishResult r =
      polish_by_correlation(k.measure(), k.start, at_start, k.centre_ct, CorrelationPolishOptions{});
  EXPECT_EQ(r.steps, 1);
  EXPECT_FALSE(r.converged);
  EXPECT_TRUE(r.pose.isApprox(k.start));
  EXPECT_DOUBLE_EQ(r.correlation, r.initial_correlation);
  EXPECT_EQ(k.measured, 1) << "the start's measurement is kept, not rendered again";
  EXPECT_DOUBLE_EQ(r.at_pose.views[0].correlation, at_start.views[0].correlation);
}

}  // namespace
}  // namespace fluoro
