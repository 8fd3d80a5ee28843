#pragma once
// Dark circles (steel balls in a log-domain X-ray, the drill guide's spheres) found by a circle
// Hough transform that counts a vote only when the gradient points away from the centre, verified
// by the edge's angular coverage, and located to sub-pixel accuracy by an intensity centroid.
#include <Eigen/Core>
#include <vector>

#include "engine/image.hpp"

namespace fluoro {

// Search range and acceptance of the detector.
// Radii in pixels; 0 as the largest radius means 4 % of the image's smaller side.
struct DarkCircleParams {
  double min_radius_px = 1.5;
  double max_radius_px = 0.0;
  double smoothing_sigma_px = 1.0;   // before the gradient
  double min_edge_coverage = 0.75;   // fraction of 24 angular sectors with an outward edge
};

// One detected circle: sub-pixel centre (column, row), radius at its edge, and how dark it is.
// `crowded` marks a circle whose centroid window reaches another circle, or an elongated blob
// (two overlapping balls found as one): its centre is less sure.
struct DarkCircle {
  Eigen::Vector2d centre_px;
  double radius_px = 0;
  double contrast = 0;        // background minus intensity at the centre (image units)
  double edge_coverage = 0;   // in [0, 1]
  double elongation = 1;      // sqrt of the ratio of the blob's principal second moments
  bool crowded = false;
};

// All dark circles of `image` (darker than their surroundings), strongest first.
// The image is not modified; an empty image gives no circles.
std::vector<DarkCircle> detect_dark_circles(const Image& image, const DarkCircleParams& params = {});

// The background-subtracted intensity centroid of a dark blob of radius `radius_px` near `start`:
// the window (radius + 1.5 px) is re-centred three times; the background is a plane fitted
// on the 3-pixel ring around the window. Also the blob's elongation, sqrt(major / minor second
// moment), 1 for a round blob. Returns the start (elongation 0) when the window leaves the image.
struct BlobCentroid {
  Eigen::Vector2d centre_px;
  double elongation = 0;
};
BlobCentroid dark_blob_centroid(const Image& image, const Eigen::Vector2d& start, double radius_px);

}  // namespace fluoro
