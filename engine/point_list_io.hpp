#pragma once
// Point list files (shared/docs/FORMATS.md): {"points": [[u, v], ...]} in 2D or
// {"points": [[x, y, z], ...]} in 3D, `null` marking a missing point. Reads validate; writes are atomic.
#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

namespace fluoro {

using PointList2 = std::vector<std::optional<Eigen::Vector2d>>;
using PointList3 = std::vector<std::optional<Eigen::Vector3d>>;

// Throws InputError naming the path for a missing file, bad JSON, a missing "points" array, a point
// of the wrong dimension or a non-finite coordinate. `null` entries are kept as std::nullopt.
PointList2 read_points_2d(const std::string& path);
PointList3 read_points_3d(const std::string& path);

// As read_points_3d, but a `null` entry is bad input too (paired lists, targets): every point present.
std::vector<Eigen::Vector3d> read_complete_points_3d(const std::string& path);

void write_points_2d(const PointList2& points, const std::string& path);
void write_points_3d(const PointList3& points, const std::string& path);

}  // namespace fluoro
