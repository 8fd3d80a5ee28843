#pragma once
// The normalised direct linear transform (Hartley): a 3x4 projection matrix from 3D-2D pairs.
#include <Eigen/Core>
#include <optional>
#include <vector>

namespace fluoro {

using Projection = Eigen::Matrix<double, 3, 4>;

// P with ||P|| = 1, signed so that the points lie in front of the camera (positive depth), from
// at least 6 pairs. Points and pixels are each centred and scaled (to sqrt(3) and sqrt(2) mean
// distance) before the SVD so the solution does not depend on units. nullopt when fewer than 6
// pairs are given or the pairs do not fix P (collinear or coplanar points: a null space of
// dimension > 1).
std::optional<Projection> projection_dlt(const std::vector<Eigen::Vector3d>& points,
                                         const std::vector<Eigen::Vector2d>& pixels);

// Pixel of a world point under P (NaN behind the camera).
Eigen::Vector2d project_with(const Projection& P, const Eigen::Vector3d& x);

}  // namespace fluoro
