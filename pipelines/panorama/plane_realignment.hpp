#pragma once
// Realignment to the bone's plane (seed ch. 3, eqs. 8-10): the homographies of two parallel planes
// between fronto-parallel frames differ only by a scale of the translation; a contour fixes it.
#include <Eigen/Core>
#include <optional>
#include <utility>
#include <vector>

namespace fluoro {

// The scale of the translations from the ruler's plane to the plane of a contour traced on two
// consecutive frames: for each point of the second contour, rotated into the first frame, the
// distance along the translation to the first contour (seed ch. 3, realignment). Returns
// {scale, standard error}; nullopt when fewer than 5 points cross the first contour.
std::optional<std::pair<double, double>> contour_plane_scale(const std::vector<Eigen::Vector2d>& first,
                                                             const std::vector<Eigen::Vector2d>& second,
                                                             const Eigen::Matrix2d& rotation_second_to_first,
                                                             const Eigen::Vector2d& centre,
                                                             const Eigen::Vector2d& ruler_translation);

}  // namespace fluoro
