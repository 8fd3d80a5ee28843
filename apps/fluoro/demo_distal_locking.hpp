#pragma once
// fluoro demo --distal-locking: one generated distal-locking X-ray with known truth (drill guide,
// nail with its holes, bone, clutter, noise), located as `fluoro distal-lock` does, the robot's goal
// computed, and what the robot would drill compared with the true hole axes.
#include <string>

namespace fluoro::cli {

struct DistalLockingDemoOptions {
  std::string out_dir = "out/demo_distal_locking";
  int pixels = 1024;      // square image
  double tilt_deg = 8;    // angle between the hole axes and the ray through the nail
  bool interactive = false;
};

void run_distal_locking_demo(const DistalLockingDemoOptions& options);

}  // namespace fluoro::cli
