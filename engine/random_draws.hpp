#pragma once
// Random vectors drawn in a fixed order. The arguments of a function call are evaluated in an
// unspecified order (GCC right to left, clang left to right), so Eigen::Vector3d(d(rng), d(rng),
// d(rng)) made other scenes, start poses and restarts under another compiler from the same seed.
// These draw the last component first, the order GCC used, so every number measured and
// documented before stays as it was.
#include <Eigen/Core>

namespace fluoro {

template <class Distribution, class Rng>
Eigen::Vector2d draw2(Distribution& d, Rng& rng) {
  const double y = d(rng);
  const double x = d(rng);
  return {x, y};
}

template <class Distribution, class Rng>
Eigen::Vector3d draw3(Distribution& d, Rng& rng) {
  const double z = d(rng);
  const double y = d(rng);
  const double x = d(rng);
  return {x, y, z};
}

}  // namespace fluoro
