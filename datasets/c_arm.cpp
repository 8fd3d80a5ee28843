#include "datasets/c_arm.hpp"

#include <cmath>
#include <numbers>

namespace fluoro {

PinholeCamera c_arm_view(const CArmGeometry& g, double orbit_deg, double tilt_deg) {
  const double a = orbit_deg * std::numbers::pi / 180.0, b = tilt_deg * std::numbers::pi / 180.0;
  const Eigen::Vector3d towards_source(std::sin(a) * std::cos(b), std::cos(a) * std::cos(b), std::sin(b));
  const Eigen::Vector3d source = g.source_to_isocentre_mm * towards_source;
  const Eigen::Vector3d down = Eigen::Vector3d(0, 0, -1);
  PinholeCamera c = PinholeCamera::look_at(source, Eigen::Vector3d::Zero(), down,
                                           g.source_to_detector_mm / g.pixel_mm, g.pixels, g.pixels);
  c.pixel_spacing_mm = Eigen::Vector2d(g.pixel_mm, g.pixel_mm);
  return c;
}

}  // namespace fluoro
