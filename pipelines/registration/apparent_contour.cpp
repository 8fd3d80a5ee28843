#include "pipelines/registration/apparent_contour.hpp"

namespace fluoro {

bool on_apparent_contour(const BoneMesh& mesh, const BoneMesh::Edge& e, const Eigen::Vector3d& source_ct,
                         ContourPoint& out) {
  const Eigen::Vector3d& a = mesh.vertices[e.a];
  const Eigen::Vector3d& b = mesh.vertices[e.b];
  // The plane through the source and the edge; both opposite vertices on one side of it means
  // the surface turns back at this edge as seen from the source.
  const Eigen::Vector3d m = (a - source_ct).cross(b - source_ct);
  const double l = m.dot(mesh.vertices[e.left] - a), r = m.dot(mesh.vertices[e.right] - a);
  if (!(l * r > 0)) return false;
  out = {0.5 * (a + b), (b - a).normalized()};
  return true;
}

std::vector<ContourPoint> apparent_contour(const BoneMesh& mesh, const Eigen::Vector3d& source_ct) {
  std::vector<ContourPoint> out;
  ContourPoint c;
  for (const BoneMesh::Edge& e : mesh.edges)
    if (on_apparent_contour(mesh, e, source_ct, c)) out.push_back(c);
  return out;
}

}  // namespace fluoro
