// Registration error measures against hand-computed values.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "datasets/c_arm.hpp"
#include "datasets/phantom.hpp"
#include "pipelines/registration/error_metrics.hpp"

namespace fluoro {
namespace {

TEST(ErrorMetrics, PureTranslationMovesEveryPointByItsLength) {
  const std::vector<Eigen::Vector3d> surface = {{0, 0, 0}, {50, 0, 0}, {0, 60, 10}, {-20, 5, 40}};
  const Pose truth = pose_from_rotation_vector(Eigen::Vector3d(0.1, 0.2, 0.3), Eigen::Vector3d(5, 6, 7));
  Pose estimate = truth;
  estimate.translation() += Eigen::Vector3d(3, 0, 4);
  const CArmGeometry g;
  const PinholeCamera ap = c_arm_view(g, 0);
  const RegistrationErrors e = registration_errors(estimate, truth, surface, {surface[0]}, {ap});
  EXPECT_NEAR(e.surface_tre_mean_mm, 5.0, 1e-9);
  EXPECT_NEAR(e.surface_tre_max_mm, 5.0, 1e-9);
  EXPECT_NEAR(e.fiducial_tre_mean_mm, 5.0, 1e-9);
  EXPECT_NEAR(e.translation_mm, 5.0, 1e-9);
  EXPECT_NEAR(e.rotation_deg, 0.0, 1e-9);
  // The AP view looks along -y, so a shift in x and z lies parallel to the detector: it projects
  // to 5 mm times the magnification, source-detector distance over the point's depth.
  double expected = 0;
  for (const auto& p : surface) expected += 5.0 * g.source_to_detector_mm / (ap.R * (truth * p) + ap.t).z();
  EXPECT_NEAR(e.mpd_mm, expected / double(surface.size()), 1e-9);
}

TEST(ErrorMetrics, RotationAboutAPointLeavesItInPlace) {
  const Eigen::Vector3d centre(10, 20, 30);
  const double angle = 2.0 * std::numbers::pi / 180.0;
  Pose rotate = Pose::Identity();
  rotate.linear() = Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  rotate.translation() = centre - rotate.linear() * centre;
  const std::vector<Eigen::Vector3d> surface = {centre, centre + Eigen::Vector3d(100, 0, 0)};
  const RegistrationErrors e = registration_errors(rotate, Pose::Identity(), surface, {}, {});
  EXPECT_NEAR(e.rotation_deg, 2.0, 1e-9);
  EXPECT_NEAR(e.surface_tre_max_mm, 2 * 100 * std::sin(angle / 2), 1e-9);  // chord of the arc
  EXPECT_NEAR(e.surface_tre_mean_mm, 100 * std::sin(angle / 2), 1e-9);
  EXPECT_TRUE(std::isnan(e.fiducial_tre_mean_mm));
  EXPECT_TRUE(std::isnan(e.mpd_mm));  // no views
}

TEST(ErrorMetrics, SurfacePointsLieOnTheBoneBoundary) {
  PhantomParams p;
  p.size = 64;
  const Phantom ph = make_phantom(p);
  const auto pts = surface_points(ph.hu, 700, 500);
  ASSERT_EQ(pts.size(), 500u);
  for (const auto& x : pts) {
    const Eigen::Vector3i idx = ph.hu.geometry.physical_to_index(x).array().round().cast<int>();
    EXPECT_GE(ph.hu.at(idx.x(), idx.y(), idx.z()), 700.0f);
  }
  EXPECT_TRUE(surface_points(ph.hu, 5000, 100).empty());  // nothing that dense
}

}  // namespace
}  // namespace fluoro
