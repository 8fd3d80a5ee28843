// Distortion correction on generated grid X-rays with a known distortion: the map's error measured
// between the holes (not at the centres it was fitted to), in plate millimetres, after removing the
// similarity the program is free to choose; the CLI's files, nulls and exit codes.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "datasets/dewarp_grid.hpp"
#include "engine/json_io.hpp"
#include "engine/point_list_io.hpp"
#include "pipelines/calibration/dewarp_fit.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

struct Residual {
  double mean_mm = 1e9, max_mm = 1e9;
  int samples = 0;
};

// Errors at points between holes (cells whose four corner holes show: the goal's points) and
// elsewhere in the map's field of view (cells under the occluder, the ring outside the last holes).
struct MapResidual {
  Residual between, elsewhere;
};

void add(Residual& r, double e) {
  if (r.samples == 0) r.mean_mm = r.max_mm = 0;
  r.mean_mm += e, r.max_mm = std::max(r.max_mm, e), ++r.samples;
}

// The map's corrected positions against the truth's ideal ones, at 16 points per lattice cell
// (cell centres included) wherever the map is defined, after the best similarity fitted on the
// visible hole centres, in plate mm.
MapResidual map_residual(const DewarpScene& s, const DewarpMap& map) {
  std::vector<Eigen::Vector2d> fitted, ideal;
  std::vector<uint8_t> visible(size_t(s.grid.rows) * size_t(s.grid.cols), 0);
  for (const auto& h : s.holes) {
    if (!h.visible) continue;
    visible[size_t(h.row) * size_t(s.grid.cols) + size_t(h.col)] = 1;
    if (const auto c = map.correct_point(h.distorted_px)) fitted.push_back(*c), ideal.push_back(h.ideal_px);
  }
  MapResidual r;
  if (fitted.size() < 3) return r;
  Eigen::Matrix2Xd from(2, fitted.size()), to(2, fitted.size());
  for (size_t k = 0; k < fitted.size(); ++k) from.col(Eigen::Index(k)) = fitted[k], to.col(Eigen::Index(k)) = ideal[k];
  const Eigen::Matrix3d sim = Eigen::umeyama(from, to, true);
  const double mm_per_px = 1.0 / s.px_per_plate_mm();
  auto vis = [&](int row, int col) { return visible[size_t(row) * size_t(s.grid.cols) + size_t(col)] != 0; };
  for (int row = 0; row < s.grid.rows - 1; ++row)
    for (int col = 0; col < s.grid.cols - 1; ++col) {
      const bool between = vis(row, col) && vis(row + 1, col) && vis(row, col + 1) && vis(row + 1, col + 1);
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) {
          const Eigen::Vector2d plate = s.grid.hole_mm(row + (a + 0.5) / 4, col + (b + 0.5) / 4);
          const Eigen::Vector2d id = s.ideal_of_plate(plate), d = s.distortion.distort(id);
          if ((d - s.fov_centre_px).norm() > s.fov_radius_px - 2) continue;
          const auto c = map.correct_point(d);
          if (!c) continue;
          const double e = ((sim.topLeftCorner<2, 2>() * *c + sim.topRightCorner<2, 1>()) - id).norm() * mm_per_px;
          add(between ? r.between : r.elsewhere, e);
        }
    }
  for (Residual* x : {&r.between, &r.elsewhere})
    if (x->samples > 0) x->mean_mm /= x->samples;
  return r;
}

DewarpSceneOptions small_scene(uint64_t seed, double orbit_deg) {
  DewarpSceneOptions o;
  o.size = 512;
  o.pixel_mm = 0.19;  // 0.38 mm pixels at 512: a 4.5-inch intensifier's crop, holes as wide as at 1024
  o.seed = seed;
  o.orbit_deg = orbit_deg;
  return o;
}

TEST(DewarpScene, DistortionAsAskedAndDifferentPerOrientation) {
  DewarpSceneOptions o = small_scene(1, 0);
  o.size = 128, o.pixel_mm = 0.38 / 8, o.supersampling = 1;
  const DewarpScene a = make_dewarp_scene(o);
  o.orbit_deg = 90;
  const DewarpScene b = make_dewarp_scene(o);
  double worst_a = 0, diff = 0;
  for (int k = 0; k < 360; ++k) {
    const Eigen::Vector2d p = a.fov_centre_px + a.fov_radius_px * Eigen::Vector2d(std::cos(k * M_PI / 180), std::sin(k * M_PI / 180));
    worst_a = std::max(worst_a, (a.distortion.distort(p) - p).norm());
    diff = std::max(diff, (a.distortion.distort(p) - b.distortion.distort(p)).norm());
    EXPECT_NEAR((a.distortion.undistort(a.distortion.distort(p)) - p).norm(), 0, 1e-8);
  }
  EXPECT_NEAR(worst_a, 12.0 * 128 / 1024, 0.05);  // 12 px at 1024, scaled
  EXPECT_GT(diff, 0.1 * worst_a);
}

struct BothModels {
  DewarpFit poly, bilinear;
  MapResidual poly_error, bilinear_error;
};

BothModels fit_both(const DewarpScene& s, const char* label) {
  BothModels m;
  DewarpFitOptions o;
  if (const char* d = std::getenv("DEWARP_DEGREE")) o.max_degree = std::atoi(d);
  m.poly = fit_dewarp(s.image, s.grid, o);
  o.model = DewarpModel::bilinear;
  m.bilinear = fit_dewarp(s.image, s.grid, o);
  if (m.poly.ok) m.poly_error = map_residual(s, *m.poly.map);
  if (m.bilinear.ok) m.bilinear_error = map_residual(s, *m.bilinear.map);
  std::printf("%s: %zu holes in the FOV, %.0f%% hidden, %d found, %d used; between holes (mm): polynomial mean %.4f max %.4f, "
              "bilinear mean %.4f max %.4f (%d samples); elsewhere: polynomial mean %.4f max %.4f, bilinear mean %.4f max %.4f (%d)\n",
              label, s.holes.size(), 100 * s.hidden_fraction, m.poly.holes_found, m.poly.holes_used, m.poly_error.between.mean_mm,
              m.poly_error.between.max_mm, m.bilinear_error.between.mean_mm, m.bilinear_error.between.max_mm,
              m.poly_error.between.samples, m.poly_error.elsewhere.mean_mm, m.poly_error.elsewhere.max_mm,
              m.bilinear_error.elsewhere.mean_mm, m.bilinear_error.elsewhere.max_mm, m.poly_error.elsewhere.samples);
  return m;
}

TEST(Dewarp, CleanGridRecoveredBetweenHoles) {
  const DewarpScene s = make_dewarp_scene(small_scene(3, 30));
  const BothModels m = fit_both(s, "clean");
  ASSERT_TRUE(m.poly.ok) << m.poly.reason;
  ASSERT_TRUE(m.bilinear.ok) << m.bilinear.reason;
  EXPECT_GT(m.poly_error.between.samples, 2000);
  EXPECT_LT(m.poly_error.between.mean_mm, 0.01);
  EXPECT_LT(m.bilinear_error.between.mean_mm, 0.03);
}

TEST(Dewarp, NoisyGridWithHiddenHolesMeetsTheGoal) {
  DewarpSceneOptions o = small_scene(5, 120);
  o.noise_sigma = 0.05;
  o.hidden_fraction = 0.35;
  o.dust_count = 30;
  const DewarpScene s = make_dewarp_scene(o);
  const BothModels m = fit_both(s, "noisy");
  ASSERT_TRUE(m.poly.ok) << m.poly.reason;
  ASSERT_TRUE(m.bilinear.ok) << m.bilinear.reason;
  EXPECT_NEAR(s.hidden_fraction, 0.35, 0.03);
  EXPECT_LT(m.poly_error.between.mean_mm, 0.05);
  EXPECT_LT(m.poly_error.between.max_mm, 0.2);
}

}  // namespace
}  // namespace fluoro
