#pragma once
// Lattice indices for detected hole centres: patches grown from seed holes, each new hole predicted
// by a local affine fit of its indexed neighbours (no global small-distortion assumption), and
// patches an occluder cut apart joined at the index offset one smooth field verifies.
#include <Eigen/Core>
#include <vector>

namespace fluoro {

// Blob `blob` sits at lattice node (i, j); i runs along the image's columns, j along its rows.
struct LatticeHole {
  int i = 0, j = 0;
  int blob = 0;
};

// (0, 0) is the indexed hole nearest `centre`. Blobs off the lattice (dust) and patches whose offset
// is ambiguous are left out. Empty when no hole has a square cross of four neighbours.
std::vector<LatticeHole> pair_lattice(const std::vector<Eigen::Vector2d>& centres, const Eigen::Vector2d& centre);

// Least-squares affine map lattice (i, j) -> pixels through the given nodes near (i0, j0):
// returns false when they do not span the plane. A is 2x2 (columns: the lattice vectors), t the origin.
bool local_lattice_affine(const std::vector<LatticeHole>& holes, const std::vector<Eigen::Vector2d>& centres, int i0,
                          int j0, int radius, Eigen::Matrix2d& A, Eigen::Vector2d& t);

}  // namespace fluoro
