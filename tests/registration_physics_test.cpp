// Registration of X-rays that do not follow the DRR model: beam hardening, scatter, detector blur
// and quantum noise together (issue 14's numbers), against the known pose of a generated scene.
#include <gtest/gtest.h>

#include <cstdio>

#include "pipelines/sweep/sweep.hpp"

namespace fluoro {
namespace {

TEST(RegistrationPhysics, CombinedImagingPhysicsFromTenMillimetresEndsUnderAThirdOfAMillimetre) {
  // A small pelvis phantom (64^3, 4 mm voxels) and three 256^2 views. Without the gradient
  // correlation's final stage these two runs end 0.57 and 0.70 mm off (the GPR score's optimum
  // is a plateau under this physics), with it 0.13 and 0.07 mm (docs/registration.md).
  SweepConfig c;
  c.phantom.kind = PhantomKind::pelvis;
  c.phantom.size = 64;
  c.c_arm.pixels = 256;
  c.c_arm.pixel_mm = 1.2;
  c.from_mm = c.to_mm = 10;
  c.runs_per_distance = 2;
  c.contours = SweepContours::automatic;
  c.physics.beam_hardening = 0.06;
  c.physics.scatter_to_primary = 0.25;
  c.physics.blur_px = 1;
  c.physics.photons = 20000;
  // The default polish mode: these X-rays depart from the DRR model (every view correlates
  // under 0.99 of its expectation), so it polishes.
  ASSERT_EQ(c.correlation_polish, CorrelationPolish::when_needed);
  const SweepScene scene(c);
  for (const SweepRun& run : plan_sweep(c)) {
    const SweepRow row = scene.run(run);
    std::printf("run %d: %.3f mm, gradient correlation %.3f\n", run.index, row.final_tre_mm, row.gradient_correlation);
    EXPECT_NEAR(row.initial_tre_mm, 10.0, 1e-3);
    EXPECT_LT(row.final_tre_mm, 0.3) << "run " << run.index;
    EXPECT_TRUE(row.confident) << "run " << run.index;
  }
}

}  // namespace
}  // namespace fluoro
