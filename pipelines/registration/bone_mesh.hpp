#pragma once
// A bone surface mesh from a CT, for the coarse contour registration: a closed triangle mesh of
// the voxels at or above an iso-value (or of a bone mask), with each interior edge knowing its
// two faces so the apparent contour seen from any source can be found edge by edge.
#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "engine/volume.hpp"

namespace fluoro {

struct BoneMesh {
  std::vector<Eigen::Vector3d> vertices;        // CT frame, mm
  std::vector<std::array<int, 3>> triangles;    // vertex indices
  // Edges shared by exactly two triangles: the edge's vertices and the vertex opposite it in
  // each triangle (what decides whether the surface folds away from a viewer there).
  struct Edge {
    int a, b;            // the edge
    int left, right;     // the opposite vertex in each of its two triangles
  };
  std::vector<Edge> edges;

  Eigen::Vector3d centroid() const;
};

struct BoneMeshParams {
  // The mesh is built on a grid coarsened by an integer factor (box average) until its smallest
  // spacing reaches this: the coarse step needs the shape, not sub-millimetre detail.
  double max_voxel_mm = 2.0;
  // ... and further, while the mesh has more triangles than this (a whole skeleton at 1 mm
  // would make every ICP iteration slow for no gain in the coarse step).
  size_t max_triangles = 60000;
  // Taubin smoothing passes that remove the voxel staircase (see bone_mesh.cpp).
  int smoothing_iterations = 20;
};

// Surface of {HU >= iso_hu}. Throws InputError naming `what` when no voxel reaches iso_hu.
BoneMesh bone_mesh_from_iso(const Volume& hu, double iso_hu, const BoneMeshParams& params, const std::string& what);

// What the triangle limit is checked on, for the surface of {mask != 0} (padded by one empty
// voxel): the lower bound of marching cubes' triangles counted on the mask (bone_mesh.cpp) and
// ITK's own count. For the tests, which check that the first never exceeds the second.
struct MarchingCubesCount {
  size_t lower_bound = 0, triangles = 0;
};
MarchingCubesCount marching_cubes_count(const Volume& mask);

// Surface of {mask != 0}; the mask has its own geometry (usually the CT's). Throws InputError
// naming `what` for an empty mask.
BoneMesh bone_mesh_from_mask(const Volume& mask, const BoneMeshParams& params, const std::string& what);

}  // namespace fluoro
