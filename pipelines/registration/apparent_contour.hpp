#pragma once
// The apparent contour of a bone surface mesh seen from an X-ray source: the mesh edges where the
// surface folds away from the viewer, i.e. the edges whose two triangles lie on the same side of
// the plane through the source and the edge. The test needs no consistent face orientation.
#include <Eigen/Geometry>
#include <vector>

#include "pipelines/registration/bone_mesh.hpp"

namespace fluoro {

struct ContourPoint {
  Eigen::Vector3d point;      // midpoint of the contour edge, CT frame
  Eigen::Vector3d direction;  // unit direction of the edge, CT frame
};

// `source_ct` is the X-ray source in the CT frame.
std::vector<ContourPoint> apparent_contour(const BoneMesh& mesh, const Eigen::Vector3d& source_ct);

// The same test for one edge: true, with its contour point in `out`, when the edge is on the
// apparent contour (for callers that split the edges between threads).
bool on_apparent_contour(const BoneMesh& mesh, const BoneMesh::Edge& e, const Eigen::Vector3d& source_ct,
                         ContourPoint& out);

}  // namespace fluoro
