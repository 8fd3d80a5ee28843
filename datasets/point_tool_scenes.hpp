#pragma once
// Synthetic scenes with known truth for the point tools: an asymmetric closed surface (so that a
// surface registration has one answer), points sampled on a surface, and tracked pivoting poses.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "engine/pose.hpp"
#include "engine/triangle_mesh.hpp"

namespace fluoro {

// A closed, lumpy ellipsoid (semi-axes 45, 30, 20 mm, three bumps and a dent at asymmetric places)
// on a latitude-longitude grid of `rings` rings: 4 rings (rings - 1) triangles. No symmetry.
TriangleMesh make_lumpy_surface(int rings);

// n points uniformly distributed over the mesh's area (deterministic for a seed).
std::vector<Eigen::Vector3d> sample_surface(const TriangleMesh& mesh, size_t n, uint64_t seed);

// n poses T_tracker_tool of a tool pivoting about `pivot_in_tracker` with its tip at `tip_in_tool`:
// random rotations up to max_angle_deg about random axes of a base orientation; then every pose's
// translation gets isotropic Gaussian noise of noise_mm per axis.
std::vector<Pose> make_pivot_poses(const Eigen::Vector3d& tip_in_tool, const Eigen::Vector3d& pivot_in_tracker, size_t n,
                                   double max_angle_deg, double noise_mm, uint64_t seed);

}  // namespace fluoro
