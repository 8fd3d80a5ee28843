#pragma once
// The nail in one X-ray (the seed, section 4.4.2): its band found by a Hough transform for two
// parallel lines a nail's width apart, darker between them than outside; its locking holes as the
// brightest windows along the band's medial axis; an ellipse per hole from the outline of its
// bright lens (OpenCV's fitEllipse on the contour at half the hole's contrast, and the lens's at
// 75 %), leaving out the outline next to known occluders (the guide's spheres).
#include <Eigen/Core>
#include <string>
#include <vector>

#include "engine/distal_locking_models.hpp"
#include "engine/image.hpp"
#include "pipelines/calibration/dark_circle_detector.hpp"

namespace fluoro {

// A line n . x = rho in pixels (n unit), the image's (column, row) coordinates.
struct ImageLine {
  Eigen::Vector2d normal;
  double rho = 0;
};

struct NailBand {
  ImageLine edge_a, edge_b;     // the two edges, normals pointing the same way
  Eigen::Vector2d axis_point;   // on the medial axis
  Eigen::Vector2d direction;    // unit, along the band
  double width_px = 0;
  double contrast = 0;          // outside minus inside, image units
};

struct HoleEllipse {
  Eigen::Vector2d centre_px;
  double major_px = 0, minor_px = 0;  // full axes
  double angle_deg = 0;               // of the major axis from the u axis
  double lens_major_px = 0, lens_minor_px = 0;  // the see-through lens's ellipse
};

struct NailDetection {
  bool ok = false;
  std::string failure_reason;   // "no nail" or "holes not separable: ..."
  NailBand band;
  std::vector<HoleEllipse> holes;  // ordered along band.direction
};

// `min_width_px`, `max_width_px`: the nail's diameter as it can appear (from its size and the
// depths the nail can be at). The holes are the brightest windows spaced as NAIL.json's (at the
// band's scale). `occluders`: dark circles whose neighbourhood is left out of the hole outlines.
NailDetection detect_nail(const Image& xray, const NailModel& nail, double min_width_px, double max_width_px,
                          const std::vector<DarkCircle>& occluders = {});

}  // namespace fluoro
