#pragma once
// Calibration-phantom X-rays with known truth: two fiducial phantoms (the seed's three-level tower
// and a denser two-plane ring), a C-arm view of a phantom mounted on the image intensifier, and a
// renderer of the exact per-pixel line integral through steel balls and clutter wires.
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "engine/camera.hpp"
#include "engine/image.hpp"
#include "engine/phantom_model.hpp"

namespace fluoro {

// The seed's tower (Sadowsky et al.): a hexagonal Delrin tower 200 mm tall in three steps of 140,
// 100 and 60 mm; 12 balls of 5 mm, four per step, placed without radial or mirror symmetry.
// Phantom frame: z along the tower's axis (towards the source), z = 0 at its base.
PhantomModel tower_phantom();

// A denser design of our own, like the FluoroTrax: 26 balls of 4 mm on two parallel rings (14 on a
// 90 mm radius at z = 10 mm, 12 on a 65 mm radius at z = 110 mm) at irregular angles.
PhantomModel ring_phantom();

// Where the phantom sits in the C-arm: mounted on the image intensifier, its axis along the beam,
// turned about that axis and tilted a little; the source `source_to_detector_mm` above the detector.
struct PhantomView {
  int pixels = 1024;                    // square detector
  double pixel_mm = 0.38;               // detector pixel size: focal length = SDD / pixel
  double source_to_detector_mm = 1000;
  double base_above_detector_mm = 40;   // the phantom's z = 0 plane above the detector
  double axis_turn_deg = 0;             // turn of the phantom about its own axis
  double tilt_deg = 0;                  // tilt of its axis away from the beam
  double tilt_azimuth_deg = 0;          // direction of that tilt in the detector plane
  Eigen::Vector2d shift_mm = Eigen::Vector2d::Zero();            // off the central ray
  Eigen::Vector2d principal_offset_px = Eigen::Vector2d::Zero();  // principal point off the image centre
};

// The true camera (phantom frame = world frame) of a view.
PinholeCamera phantom_view_camera(const PhantomView& view);

// Image formation: steel mu, partial volume at the edges, blur, quantum noise, clutter.
struct XrayRendering {
  double steel_mu_per_mm = 0.6;
  double blur_sigma_px = 0.0;       // detector + focal spot, applied to the linear intensity
  double photons_per_pixel = 0.0;   // unattenuated counts; 0 = no quantum noise
  int clutter_balls = 0;            // extra balls that belong to no model point
  int clutter_wires = 0;            // straight steel wires across the field
  uint64_t seed = 1;
};

// A rendered calibration X-ray: log-domain line integrals (mm * mu, 0 = no attenuation) and truth.
struct CalibrationScene {
  PinholeCamera camera;             // truth, phantom frame as world
  PhantomModel phantom;
  Image line_integral;              // -ln(I / I0) per pixel after blur and noise
  std::vector<Eigen::Vector3d> clutter_balls_mm;  // phantom frame
};

CalibrationScene render_calibration_scene(const PhantomModel& phantom, const PhantomView& view,
                                          const XrayRendering& rendering);

// The 16-bit log-domain PNG pixels of a line-integral image: 60000 - 10000 * L, clamped to
// [0, 65535]; bone and metal dark, as the default input convention expects.
std::vector<uint16_t> log_domain_png_pixels(const Image& line_integral);
// The same values as a float image: the X-ray as the commands read it from that PNG (balls dark).
Image log_domain_xray(const Image& line_integral);

// Writes a scene as `fluoro calibrate` takes it: `<prefix>.png` (16-bit log domain),
// `<prefix>_phantom.json` (PHANTOM.json) and `<prefix>_true_camera.json` (the truth, a camera
// file). Atomic writes; throws InputError naming a path that cannot be written.
void write_calibration_scene(const CalibrationScene& scene, const std::string& prefix);

}  // namespace fluoro
