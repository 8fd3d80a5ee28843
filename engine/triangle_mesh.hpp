#pragma once
// A triangle surface in millimetres: shared vertices and index triples. What the mesh readers
// return and the closest-point index searches; a triangle soup (STL) is a valid mesh too.
#include <Eigen/Core>
#include <array>
#include <vector>

namespace fluoro {

// Vertices (mm) and triangles as vertex index triples; winding is not relied on.
struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::array<int, 3>> triangles;
};

}  // namespace fluoro
