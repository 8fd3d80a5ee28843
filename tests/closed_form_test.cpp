// The reference backend against closed forms (RTK-style analytic checks).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

#include "engine/backend.hpp"
#include "engine/expected_edges.hpp"
#include "engine/ray_setup.hpp"
#include "kernels/backend_registry.hpp"
#include "tests/test_scenes.hpp"

namespace fluoro {
namespace {

// Chord length of the ray from c along unit d through the axis-aligned box [lo, hi].
double box_chord(const Eigen::Vector3d& c, const Eigen::Vector3d& d, const Eigen::Vector3d& lo,
                 const Eigen::Vector3d& hi) {
  double t0 = 0, t1 = 1e30;
  for (int a = 0; a < 3; ++a) {
    double ta = (lo[a] - c[a]) / d[a], tb = (hi[a] - c[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  return std::max(0.0, t1 - t0);
}

TEST(ClosedForm, UniformBoxDrrIsMuTimesChordLength) {
  auto ref = make_backend("reference");
  const double mu = 0.02;
  const Volume v = test::make_volume({20, 14, 9}, {1.5, 2.0, 3.0}, [&](const Eigen::Vector3d&) { return float(mu); });
  const auto dv = ref->upload(v);
  // An oblique view so rays cross several faces.
  const PinholeCamera cam = test::camera_looking_at_origin(300, 250, 41, 37, Eigen::Vector3d(0.3, -0.4, 1));
  const Pose pose = pose_from_rotation_vector(Eigen::Vector3d(0.1, 0.2, -0.15), Eigen::Vector3d(1, -2, 3));
  const Image img = ref->drr(*dv, std::span(&pose, 1), std::span(&cam, 1), DrrParams{0.7, {}})[0];
  const Eigen::Vector3d half(15, 14, 13.5);  // half extents: n * spacing / 2
  int hits = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      // The ray in the CT frame.
      const Eigen::Vector3d c = pose.inverse() * cam.source();
      const Eigen::Vector3d d = pose.rotation().transpose() * cam.ray_direction(x, y);
      const double expected = mu * box_chord(c, d, -half, half);
      ASSERT_NEAR(img.at(x, y), expected, 1e-9 + 1e-6 * expected) << x << "," << y;
      hits += expected > 0;
    }
  EXPECT_GT(hits, cam.width * cam.height / 4);  // the box fills a good part of the image
  EXPECT_LT(hits, cam.width * cam.height);      // and some rays miss it
}

TEST(ClosedForm, SphereDrrMatchesChordLength) {
  auto ref = make_backend("reference");
  const double r = 20.0;
  const Volume v = test::make_sphere(56, 1.0, r);
  const auto dv = ref->upload(v);
  const PinholeCamera cam = test::camera_looking_at_origin(400, 800, 33, 33);
  const Pose pose = Pose::Identity();
  const Image img = ref->drr(*dv, std::span(&pose, 1), std::span(&cam, 1), DrrParams{0.25, {}})[0];
  double max_err = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const Eigen::Vector3d c = cam.source(), d = cam.ray_direction(x, y);
      const double b = c.dot(d), disc = b * b - (c.squaredNorm() - r * r);
      const double chord = disc > 0 ? 2 * std::sqrt(disc) : 0;
      // A chord that only grazes the surface is sensitive to the voxelisation; skip the rim.
      if (disc > 0 && std::sqrt(disc) < 4) continue;
      max_err = std::max(max_err, std::abs(img.at(x, y) - chord));
    }
  // Partial-volume voxels of 1 mm blur the surface by about half a voxel at each end.
  EXPECT_LT(max_err, 0.6);
  EXPECT_NEAR(img.at(16, 16), 2 * r, 0.5);
}

TEST(ClosedForm, GradientOfLinearRampIsExactInTheInterior) {
  auto ref = make_backend("reference");
  const Eigen::Vector3d a(0.003, -0.002, 0.001);  // 1/mm^2
  // A non-identity direction (a rotation) and anisotropic spacing: the gradient is physical.
  const Eigen::Matrix3d D = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Volume v = test::make_volume({24, 20, 16}, {1.0, 1.5, 2.0},
                                     [&](const Eigen::Vector3d& x) { return float(0.05 + a.dot(x)); }, D);
  const auto grad = ref->download_gradient(*ref->gradient_field(*ref->upload(v), {2.0, 0.0}));
  // Interior: beyond the filter radius (4 sigma: 8, 6 and 4 voxels) of the clamped borders.
  for (int k = 4; k < 16 - 4; ++k)
    for (int j = 6; j < 20 - 6; ++j)
      for (int i = 8; i < 24 - 8; ++i) {
        const auto& g = grad.at(i, j, k);
        for (int c = 0; c < 3; ++c) ASSERT_NEAR(g[size_t(c)], a[c], 2e-7) << i << "," << j << "," << k;
      }
}

TEST(ClosedForm, ProjectionOfKnownPoints) {
  PinholeCamera cam;
  cam.width = 640;
  cam.height = 480;
  cam.K << 1000, 0.5, 320, 0, 1100, 240, 0, 0, 1;
  cam.R = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0, 1, 0)).toRotationMatrix();
  cam.t = Eigen::Vector3d(10, -20, 800);
  const Eigen::Vector3d x(30, 40, 50);
  const Eigen::Vector3d xc = cam.R * x + cam.t;
  const Eigen::Vector2d expected(1000 * xc.x() / xc.z() + 0.5 * xc.y() / xc.z() + 320, 1100 * xc.y() / xc.z() + 240);
  const Eigen::Vector2d p = cam.project(x);
  EXPECT_NEAR(p.x(), expected.x(), 1e-9);
  EXPECT_NEAR(p.y(), expected.y(), 1e-9);
  // The ray through that pixel passes through the point.
  const Eigen::Vector3d d = cam.ray_direction(p.x(), p.y());
  const Eigen::Vector3d cx = x - cam.source();
  EXPECT_NEAR((cx - cx.dot(d) * d).norm(), 0.0, 1e-9);
  // A point behind the source does not project.
  EXPECT_TRUE(std::isnan(cam.project(cam.source() - 10 * cam.R.row(2).transpose()).x()));
  // The same through P = K [R | t].
  const Eigen::Vector3d ph = cam.projection_matrix() * x.homogeneous();
  EXPECT_NEAR(ph.x() / ph.z(), expected.x(), 1e-9);
  // And through the decomposition of a scaled P.
  const PinholeCamera back = camera_from_projection(-2.5 * cam.projection_matrix(), 640, 480, "P");
  EXPECT_TRUE(back.K.isApprox(cam.K, 1e-9));
  EXPECT_TRUE(back.R.isApprox(cam.R, 1e-9));
  EXPECT_TRUE(back.t.isApprox(cam.t, 1e-9));
}

// A volume stored with a non-identity direction renders the same DRR as its identity-direction
// copy. The direction here permutes and flips axes, so the copy is an exact re-indexing.
TEST(ClosedForm, NonIdentityDirectionRendersLikeItsResampledCopy) {
  auto ref = make_backend("reference");
  auto blob = [](const Eigen::Vector3d& x) {
    return float(0.02 * std::exp(-(x - Eigen::Vector3d(5, -8, 3)).squaredNorm() / 200.0) +
                 0.01 * (std::abs(x.x() + 2 * x.y()) < 10));
  };
  const Eigen::Vector3i n(18, 22, 14);
  const Eigen::Vector3d s(1.2, 1.0, 1.5);
  Eigen::Matrix3d D;  // i -> -y, j -> +z, k -> -x
  D << 0, 0, -1, -1, 0, 0, 0, 1, 0;
  ASSERT_NEAR(D.determinant(), 1.0, 1e-12);
  const Volume rotated = test::make_volume(n, s, blob, D);
  // Build the identity copy by re-indexing the rotated volume's voxels.
  Volume identity;
  identity.geometry.size = Eigen::Vector3i(n.z(), n.x(), n.y());
  identity.geometry.spacing = Eigen::Vector3d(s.z(), s.x(), s.y());
  identity.geometry.origin = rotated.geometry.index_to_physical(Eigen::Vector3d(n.x() - 1, 0, n.z() - 1));
  identity.voxels.resize(identity.geometry.voxel_count());
  for (int k = 0; k < n.z(); ++k)
    for (int j = 0; j < n.y(); ++j)
      for (int i = 0; i < n.x(); ++i) {
        const Eigen::Vector3d x = rotated.geometry.index_to_physical(Eigen::Vector3d(i, j, k));
        const Eigen::Vector3d q = identity.geometry.physical_to_index(x);
        const Eigen::Vector3i qi = q.array().round().cast<int>();
        ASSERT_LT((q - qi.cast<double>()).norm(), 1e-9);
        identity.at(qi.x(), qi.y(), qi.z()) = rotated.at(i, j, k);
      }
  const PinholeCamera cam = test::camera_looking_at_origin(300, 600, 29, 31, Eigen::Vector3d(0.2, 0.5, 1));
  const Pose pose = pose_from_rotation_vector(Eigen::Vector3d(0.2, -0.1, 0.3), Eigen::Vector3d(2, 1, -3));
  const Image a = ref->drr(*ref->upload(rotated), std::span(&pose, 1), std::span(&cam, 1), DrrParams{0.5, {}})[0];
  const Image b = ref->drr(*ref->upload(identity), std::span(&pose, 1), std::span(&cam, 1), DrrParams{0.5, {}})[0];
  double max_v = 0;
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    ASSERT_NEAR(a.pixels[i], b.pixels[i], 1e-5) << i;
    max_v = std::max(max_v, double(a.pixels[i]));
  }
  EXPECT_GT(max_v, 0.1);
}

// The gradient projection is the derivative of the DRR with respect to the pixel position
// (seed, chapter 2, eq. 1): compare with central differences of the reference DRR.
TEST(ClosedForm, GradientProjectionIsTheDrrDerivative) {
  auto ref = make_backend("reference");
  // Smooth anatomy, so the Gaussian derivative (small sigma) barely changes it.
  auto f = [](const Eigen::Vector3d& x) {
    return float(0.03 * std::exp(-(x - Eigen::Vector3d(4, -3, 2)).squaredNorm() / (2 * 12.0 * 12.0)) +
                 0.02 * std::exp(-(x + Eigen::Vector3d(8, 5, 0)).squaredNorm() / (2 * 8.0 * 8.0)));
  };
  const Volume v = test::make_volume({64, 64, 64}, {1, 1, 1}, f);
  const auto mu = ref->upload(v);
  const auto grad = ref->gradient_field(*mu, {0.5, 0.0});
  const PinholeCamera cam = test::camera_looking_at_origin(500, 1000, 64, 64, Eigen::Vector3d(0.1, 0.2, 1));
  const Pose pose = pose_from_rotation_vector(Eigen::Vector3d(0.1, 0, 0.2), Eigen::Vector3d(1, 2, 0));
  std::vector<Eigen::Vector2f> px;
  for (int y = 8; y < 56; y += 6)
    for (int x = 8; x < 56; x += 6) px.emplace_back(float(x), float(y));
  const std::vector<Eigen::Vector2f> pixels[] = {px};
  const auto g = ref->gradient_projection(*grad, std::span(&pose, 1), std::span(&cam, 1), pixels, {0.25})[0];
  // Central differences of the DRR over +-1 pixel (windows of 3 x 3 around each pixel).
  const auto drr = ref->drr(*mu, std::span(&pose, 1), std::span(&cam, 1), DrrParams{0.25, {}})[0];
  double max_err = 0, max_g = 0;
  for (size_t i = 0; i < px.size(); ++i) {
    const int x = int(px[i].x()), y = int(px[i].y());
    const Eigen::Vector2d fd(0.5 * (drr.at(x + 1, y) - drr.at(x - 1, y)), 0.5 * (drr.at(x, y + 1) - drr.at(x, y - 1)));
    max_err = std::max(max_err, (fd - g[i].cast<double>()).norm());
    max_g = std::max(max_g, fd.norm());
  }
  EXPECT_GT(max_g, 1e-3);
  EXPECT_LT(max_err, 0.02 * max_g);
}

}  // namespace
}  // namespace fluoro

namespace fluoro {
namespace {

// The expected-edge map of a ball is a circle about the principal point just inside its
// silhouette, of radius f R / sqrt(d^2 - R^2) pixels for a ball of radius R at distance d on the
// optical axis: the edge of the smoothed ball (sigma 1 mm, plus half a voxel of partial volume)
// has its steepest projection slightly inside the rim.
TEST(ClosedForm, ExpectedEdgesOfABallTraceItsSilhouette) {
  for (const std::string& name : backend_names()) {
    std::unique_ptr<Backend> backend;
    try {
      backend = make_backend(name);
    } catch (const BackendUnavailable& e) {  // built in, no device here
      std::printf("skipping %s: %s\n", name.c_str(), e.what());
      continue;
    }
    const double r = 20.0, d = 400.0, f = 800.0;
    const auto grad = backend->gradient_field(*backend->upload(test::make_sphere(56, 1.0, r)), {1.0, 0.0});
    const PinholeCamera cam = test::camera_looking_at_origin(d, f, 97, 97);
    const ExpectedEdges e = expected_edges(*backend, *grad, Pose::Identity(), cam, {0.5, 0.2});
    const double silhouette = f * r / std::sqrt(d * d - r * r), px_per_mm = f / d;
    int edge_pixels = 0;
    double sum = 0, sum2 = 0;
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x)
        if (e.mask.at(x, y)) {
          ++edge_pixels;
          const double radius = std::hypot(x - cam.K(0, 2), y - cam.K(1, 2));
          sum += radius;
          sum2 += radius * radius;
        }
    ASSERT_GT(edge_pixels, 0) << name;
    const double mean = sum / edge_pixels, spread = std::sqrt(std::max(0.0, sum2 / edge_pixels - mean * mean));
    EXPECT_LT(mean, silhouette) << name;
    EXPECT_GT(mean, silhouette - 1.5 * px_per_mm) << name;  // within 1.5 mm of the rim
    EXPECT_LT(spread, 0.6) << name;                          // and a circle, not a band
    // A closed one-pixel ring: about its circumference in pixels.
    EXPECT_GT(edge_pixels, 0.8 * 2 * std::numbers::pi * silhouette) << name;
    EXPECT_LT(edge_pixels, 1.6 * 2 * std::numbers::pi * silhouette) << name;
  }
}

}  // namespace
}  // namespace fluoro
