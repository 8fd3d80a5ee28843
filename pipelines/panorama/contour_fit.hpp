#pragma once
// The bone plane's scale from a contour whose shared stretch runs nearly along the translation
// (a long bone's shaft): no ray along the translation crosses it cleanly, but every traced point
// still says something across it. The second contour, turned into the first frame, is moved by
// scale * translation onto the first; the scale is the least-squares one over the points' distances
// across the first contour, each point weighing by how far the scale moves it across (|t| times the
// sine of the angle between contour and translation), so a stretch along the translation weighs
// nothing. The standard error from the residuals says whether the contour fixes the plane at all.
#include <Eigen/Core>
#include <optional>
#include <vector>

namespace fluoro {

struct ContourFit {
  double scale = 1;
  double sigma = 0;        // standard error of the scale
  double residual_px = 0;  // RMS distance across the first contour after the fit
  int points = 0;          // points of the second contour matched on the first
};

// nullopt when fewer than 20 points of the second contour land on the first at any scale in
// [0.6, 1.4] (see contour_plane_scale for the arguments).
std::optional<ContourFit> contour_scale_least_squares(const std::vector<Eigen::Vector2d>& first,
                                                      const std::vector<Eigen::Vector2d>& second,
                                                      const Eigen::Matrix2d& rotation_second_to_first,
                                                      const Eigen::Vector2d& centre,
                                                      const Eigen::Vector2d& ruler_translation);

}  // namespace fluoro
