// The livewire joins clicked points along the X-ray's edges: on an image of a dark disk (a bone in
// the log domain) it follows the circle between clicks where straight segments cut across it.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "pipelines/registration/livewire.hpp"
#include "pipelines/registration/registration_io.hpp"

namespace fluoro {
namespace {

constexpr double kCx = 128.3, kCy = 121.7, kRadius = 70.0;

// A disk of radius kRadius darker than its surroundings, with a soft (about 1.5 px) edge and noise.
Image disk_image(double noise) {
  Image img(256, 256);
  std::mt19937 rng(3);
  std::normal_distribution<float> n(0.0f, float(noise));
  for (int v = 0; v < img.height; ++v)
    for (int u = 0; u < img.width; ++u) {
      const double r = std::hypot(u - kCx, v - kCy);
      img.at(u, v) = float(600.0 + 300.0 * std::tanh((r - kRadius) / 1.5)) + n(rng);
    }
  return img;
}

double worst_distance_from_circle(const std::vector<Eigen::Vector2f>& path) {
  double worst = 0;
  for (const auto& p : path) worst = std::max(worst, std::abs(std::hypot(p.x() - kCx, p.y() - kCy) - kRadius));
  return worst;
}

TEST(Livewire, FollowsTheEdgeBetweenClicksWhereStraightSegmentsCutAcross) {
  // Eight clicks on the outline, 45 degrees apart, a pixel off where a hand would put them.
  std::vector<Eigen::Vector2f> clicks;
  for (int k = 0; k <= 8; ++k) {
    const double a = k * std::numbers::pi / 4;
    const double r = kRadius + (k % 2 ? 1.0 : -1.0);
    clicks.emplace_back(float(kCx + r * std::cos(a)), float(kCy + r * std::sin(a)));
  }
  // Straight segments leave the circle by r (1 - cos 22.5 deg), about 5 px.
  EXPECT_GT(worst_distance_from_circle(sample_polyline(clicks)), 4.5);
  for (const double noise : {0.0, 10.0}) {
    const std::vector<Eigen::Vector2f> path = livewire_path(disk_image(noise), clicks);
    // Closed and connected: every step to an 8-neighbour, ending at the first click.
    ASSERT_GT(path.size(), 400u) << "noise " << noise;
    for (size_t i = 1; i < path.size(); ++i)
      EXPECT_LE((path[i] - path[i - 1]).cwiseAbs().maxCoeff(), 1.0f) << "noise " << noise << ", step " << i;
    EXPECT_LE((path.back() - path.front()).norm(), 1.0f);
    // On the edge: within a pixel and a half of the circle, away from the clicks' own offsets.
    std::vector<Eigen::Vector2f> between;
    for (const auto& p : path) {
      bool near_click = false;
      for (const auto& c : clicks) near_click = near_click || (p - c).norm() < 3.0f;
      if (!near_click) between.push_back(p);
    }
    EXPECT_LT(worst_distance_from_circle(between), 1.5) << "noise " << noise;
  }
}

TEST(Livewire, NoClicksNoPathAndOneClickOnePixel) {
  const Image img = disk_image(0.0);
  EXPECT_TRUE(livewire_path(img, {}).empty());
  const auto one = livewire_path(img, {Eigen::Vector2f(10.2f, 20.7f)});
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0], Eigen::Vector2f(10, 21));
}

}  // namespace
}  // namespace fluoro
