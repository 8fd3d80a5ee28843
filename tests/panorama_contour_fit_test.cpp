// The bone plane's scale from a contour that runs nearly along the translation
// (pipelines/panorama/contour_fit.hpp): recovered within its stated error where the contour bends a
// few degrees, and a contour exactly along the translation fixes nothing.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "engine/random_draws.hpp"
#include "pipelines/panorama/contour_fit.hpp"

namespace fluoro {
namespace {

constexpr double kDeg = M_PI / 180;

// A traced outline: points about a pixel apart with 0.3 px jitter (the generator's tracing), the
// second frame's trace offset by half a point, both from the true curve y(x).
template <typename Curve>
void traces(Curve y, double scale, std::vector<Eigen::Vector2d>& first, std::vector<Eigen::Vector2d>& second,
            const Eigen::Matrix2d& rot, const Eigen::Vector2d& centre, const Eigen::Vector2d& t) {
  std::mt19937 rng(7);
  std::normal_distribution<double> jitter(0.0, 0.3);
  for (double x = 250; x <= 480; x += 1.0) {
    first.push_back(Eigen::Vector2d(x, y(x)) + draw2(jitter, rng));
    const Eigen::Vector2d p(x + 0.5, y(x + 0.5));
    // second = rot^-1 (p - scale t - centre) + centre: moved back onto the first by the scale
    second.push_back(centre + rot.transpose() * (p - scale * t - centre) + draw2(jitter, rng));
  }
}

TEST(PanoramaContourFit, AShallowBendFixesTheScaleWithinItsStatedError) {
  const Eigen::Vector2d centre(255.5, 255.5), t(150, 4);
  const Eigen::Matrix2d rot = Eigen::Rotation2Dd(3 * kDeg).toRotationMatrix();
  std::vector<Eigen::Vector2d> first, second;
  // A waist bending at most 5.7 deg from the axis: no stretch steeper than 10 deg.
  traces([](double x) { return 200 + 4 * std::tanh((x - 390) / 40); }, 0.93, first, second, rot, centre, t);
  const auto f = contour_scale_least_squares(first, second, rot, centre, t);
  ASSERT_TRUE(f.has_value());
  EXPECT_GT(f->points, 50);
  EXPECT_LT(f->sigma, 0.01);
  EXPECT_NEAR(f->scale, 0.93, 4 * f->sigma);
  EXPECT_NEAR(f->residual_px, 0.3 * std::sqrt(1 + 1.0 / 31), 0.1);  // the traces' jitter, not a misfit
}

TEST(PanoramaContourFit, AContourAlongTheTranslationFixesNothing) {
  const Eigen::Vector2d centre(255.5, 255.5), t(150, 0);  // no information at all: the contour along the translation, the trace's jitter aside
  const Eigen::Matrix2d rot = Eigen::Matrix2d::Identity();
  std::vector<Eigen::Vector2d> first, second;
  traces([](double) { return 200.0; }, 0.93, first, second, rot, centre, t);
  const auto f = contour_scale_least_squares(first, second, rot, centre, t);
  // The jitter alone is all there is across it: either no fit or one with a useless error.
  if (f) {
    EXPECT_GT(f->sigma, 0.05);
  }
}

}  // namespace
}  // namespace fluoro
