#pragma once
// Synthetic C-arm views around an isocentre at the world origin, for the demo, tests and
// benchmarks. World axes follow LPS like the CT: x left, y posterior, z superior.
#include "engine/camera.hpp"

namespace fluoro {

struct CArmGeometry {
  double source_to_isocentre_mm = 600;
  double source_to_detector_mm = 1000;
  int pixels = 512;           // square detector
  double pixel_mm = 0.6;      // detector pixel size
};

// A view rotated by `orbit_deg` about the patient's long axis (0: AP, the source posterior, 90:
// lateral, the source on the patient's left) and tilted by `tilt_deg` towards the head. Image rows
// run from head to feet.
PinholeCamera c_arm_view(const CArmGeometry& g, double orbit_deg, double tilt_deg = 0.0);

}  // namespace fluoro
