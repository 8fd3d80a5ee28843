#pragma once
// Lattice indices for detected hole centres: grown from a seed hole near the image centre, each new
// hole predicted by a local affine fit of its already-indexed neighbours (no global small-distortion
// assumption), so occluded bands are jumped and dust off the lattice is left out.
#include <Eigen/Core>
#include <vector>

namespace fluoro {

// Blob `blob` sits at lattice node (i, j); i runs along the image's columns, j along its rows.
struct LatticeHole {
  int i = 0, j = 0;
  int blob = 0;
};

// (0, 0) is a hole near `centre` whose four neighbours form a square cross. Empty when no such seed
// exists (fewer than five holes in a cross, or no lattice at all).
std::vector<LatticeHole> pair_lattice(const std::vector<Eigen::Vector2d>& centres, const Eigen::Vector2d& centre);

// Least-squares affine map lattice (i, j) -> pixels through the given nodes near (i0, j0):
// returns false when they do not span the plane. A is 2x2 (columns: the lattice vectors), t the origin.
bool local_lattice_affine(const std::vector<LatticeHole>& holes, const std::vector<Eigen::Vector2d>& centres, int i0,
                          int j0, int radius, Eigen::Matrix2d& A, Eigen::Vector2d& t);

}  // namespace fluoro
