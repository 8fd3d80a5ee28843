// The imaging-physics simulator against closed forms (datasets/xray_physics.hpp).
#include <gtest/gtest.h>

#include <cmath>

#include "datasets/xray_physics.hpp"
#include "engine/error.hpp"

namespace fluoro {
namespace {

Image ramp(int w, int h, double top) {
  Image im(w, h);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) im.at(u, v) = float(top * u / (w - 1));
  return im;
}

TEST(XrayPhysics, EveryEffectOffGivesTheDrrBack) {
  const Image drr = ramp(64, 32, 9.0);  // beyond max_line_integral: the scale must cancel out
  const Image out = simulate_xray_physics(drr, XrayPhysics{});
  for (size_t i = 0; i < drr.pixels.size(); ++i) EXPECT_NEAR(out.pixels[i], drr.pixels[i], 1e-5f * (1 + drr.pixels[i]));
}

TEST(XrayPhysics, BeamHardeningFollowsTheQuadraticOnTheScaledLineIntegral) {
  const Image drr = ramp(101, 4, 12.0);  // scaled by 1/2 onto [0, 6]
  XrayPhysics p;
  p.beam_hardening = 0.06;
  const Image out = simulate_xray_physics(drr, p);
  for (int u = 0; u < drr.width; ++u) {
    const double l = 0.5 * drr.at(u, 2);
    EXPECT_NEAR(out.at(u, 2), (l - 0.06 * l * l) / 0.5, 1e-4) << u;
  }
  // The thickest ray: 6 - 0.06 * 36 = 3.84 in scaled units.
  EXPECT_NEAR(out.at(100, 0), 3.84 / 0.5, 1e-4);
}

TEST(XrayPhysics, ScatterOfAFlatFieldMultipliesTheIntensityByOnePlusSpr) {
  for (double spr : {0.25, 0.5, 1.0}) {
    Image drr(96, 80, 2.0f);
    XrayPhysics p;
    p.scatter_to_primary = spr;
    const Image out = simulate_xray_physics(drr, p);
    for (float v : out.pixels) ASSERT_NEAR(v, 2.0 - std::log(1 + spr), 1e-5) << spr;
  }
}

TEST(XrayPhysics, ScatterLowersTheContrastOfADenseRegion) {
  // A dense square in a thin field: the scatter reaching the square comes mostly from the bright
  // surroundings, so its apparent line integral falls by more than the flat-field log(1 + SPR).
  Image drr(128, 128, 0.5f);
  for (int v = 48; v < 80; ++v)
    for (int u = 48; u < 80; ++u) drr.at(u, v) = 4.0f;
  XrayPhysics p;
  p.scatter_to_primary = 0.25;
  p.scatter_sigma_px = 10;
  const Image out = simulate_xray_physics(drr, p);
  const double contrast_before = 4.0 - 0.5, contrast_after = out.at(64, 64) - out.at(5, 5);
  EXPECT_LT(contrast_after, contrast_before - 0.5);
  EXPECT_GT(contrast_after, 0.5);
}

TEST(XrayPhysics, DetectorBlurSpreadsAnIntensityStepAsTheErrorFunction) {
  // A step in line integral is a step in intensity, exp(-0) = 1 to exp(-1); blurred by sigma it is
  // the error function across the step.
  Image drr(200, 8, 0.0f);
  for (int v = 0; v < 8; ++v)
    for (int u = 100; u < 200; ++u) drr.at(u, v) = 1.0f;
  XrayPhysics p;
  p.blur_px = 3;
  const Image out = simulate_xray_physics(drr, p);
  for (int u = 90; u < 110; ++u) {
    const double x = u - 99.5;  // the step sits between pixels 99 and 100
    const double i = 1 + (std::exp(-1.0) - 1) * 0.5 * (1 + std::erf(x / (3 * std::sqrt(2.0))));
    EXPECT_NEAR(out.at(u, 4), -std::log(i), 2e-3) << u;
  }
}

TEST(XrayPhysics, QuantumNoiseHasPoissonVarianceInTheIntensityDomain) {
  const double line_integral = 1.5, photons = 2000;
  Image drr(256, 256, float(line_integral));
  XrayPhysics p;
  p.photons = photons;
  p.seed = 7;
  const Image out = simulate_xray_physics(drr, p);
  double sum = 0, sum2 = 0;
  for (float v : out.pixels) {
    const double i = std::exp(-double(v));
    sum += i;
    sum2 += i * i;
  }
  const double n = double(out.pixels.size()), mean = sum / n, var = sum2 / n - mean * mean;
  const double expected_mean = std::exp(-line_integral), expected_var = expected_mean / photons;  // Poisson: var = mean
  EXPECT_NEAR(mean, expected_mean, 5 * std::sqrt(expected_var / n));
  EXPECT_NEAR(var / expected_var, 1.0, 0.03);  // 65,536 samples: the ratio's std is about 0.6 %

  // Ten times the photons: a tenth of the variance.
  p.photons = 10 * photons;
  const Image quieter = simulate_xray_physics(drr, p);
  double q = 0, q2 = 0;
  for (float v : quieter.pixels) {
    const double i = std::exp(-double(v));
    q += i;
    q2 += i * i;
  }
  EXPECT_NEAR((q2 / n - (q / n) * (q / n)) / (expected_var / 10), 1.0, 0.03);
}

TEST(XrayPhysics, TheNoiseDependsOnlyOnTheSeed) {
  const Image drr = ramp(64, 64, 3.0);
  XrayPhysics p;
  p.photons = 5000;
  p.seed = 3;
  const Image a = simulate_xray_physics(drr, p), b = simulate_xray_physics(drr, p);
  EXPECT_EQ(a.pixels, b.pixels);
  p.seed = 4;
  EXPECT_NE(simulate_xray_physics(drr, p).pixels, a.pixels);
}

TEST(XrayPhysics, OutOfRangeParametersAreBadInput) {
  const Image drr(8, 8, 1.0f);
  XrayPhysics p;
  p.beam_hardening = 0.09;  // beyond 1 / (2 * 6): the curve would turn down
  EXPECT_THROW(simulate_xray_physics(drr, p), InputError);
  p = {};
  p.scatter_to_primary = -0.1;
  EXPECT_THROW(simulate_xray_physics(drr, p), InputError);
  p = {};
  p.blur_px = std::nan("");
  EXPECT_THROW(simulate_xray_physics(drr, p), InputError);
  p = {};
  p.photons = 0.5;
  EXPECT_THROW(simulate_xray_physics(drr, p), InputError);
}

}  // namespace
}  // namespace fluoro
