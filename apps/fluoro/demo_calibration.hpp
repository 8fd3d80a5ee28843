#pragma once
// fluoro demo --calibration: the calibration chain (dewarp grid, phantom, camera) on generated
// images with known truth, with its errors printed and its files written for the real commands.
#include <string>

namespace fluoro::cli {

struct CalibrationDemoOptions {
  std::string out_dir = "out/demo_calibration";
  int pixels = 1024;       // square images
  double orbit_deg = 30;   // C-arm orientation: the distortion depends on it
  bool ring = false;       // the denser ring phantom instead of the seed's tower
};

void run_calibration_demo(const CalibrationDemoOptions& options);

}  // namespace fluoro::cli
