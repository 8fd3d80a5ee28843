#pragma once
// Small synthetic volumes and cameras with known answers, shared by the test files.
#include <cmath>
#include <functional>

#include "engine/camera.hpp"
#include "engine/volume.hpp"

namespace fluoro::test {

// A volume of n voxels per axis (spacing s, identity direction) centred on the origin, filled by
// f(physical position).
inline Volume make_volume(Eigen::Vector3i n, Eigen::Vector3d s,
                          const std::function<float(const Eigen::Vector3d&)>& f,
                          Eigen::Matrix3d direction = Eigen::Matrix3d::Identity()) {
  Volume v;
  v.geometry.size = n;
  v.geometry.spacing = s;
  v.geometry.direction = direction;
  v.geometry.origin = Eigen::Vector3d::Zero();
  // Centre the box on the physical origin whatever the direction.
  v.geometry.origin = -v.geometry.physical_centre();
  v.voxels.resize(v.geometry.voxel_count());
  for (int k = 0; k < n.z(); ++k)
    for (int j = 0; j < n.y(); ++j)
      for (int i = 0; i < n.x(); ++i)
        v.at(i, j, k) = f(v.geometry.index_to_physical(Eigen::Vector3d(i, j, k)));
  return v;
}

// A camera at `distance` mm from the origin on +z... looking at the origin along -z, with focal
// length f px and an image of w x h pixels; rows along world +y.
inline PinholeCamera camera_looking_at_origin(double distance, double f, int w, int h,
                                              Eigen::Vector3d towards_source = Eigen::Vector3d(0, 0, 1)) {
  const Eigen::Vector3d up_hint = std::abs(towards_source.normalized().y()) > 0.9 ? Eigen::Vector3d(1, 0, 0)
                                                                                  : Eigen::Vector3d(0, 1, 0);
  return PinholeCamera::look_at(distance * towards_source.normalized(), Eigen::Vector3d::Zero(), up_hint, f, w, h);
}

// Sphere of radius r (mm) with value 1 inside, anti-aliased by 4^3 supersampling per voxel.
inline Volume make_sphere(int n, double spacing, double r) {
  return make_volume({n, n, n}, {spacing, spacing, spacing}, [&](const Eigen::Vector3d& x) {
    int inside = 0;
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        for (int c = 0; c < 4; ++c) {
          const Eigen::Vector3d o = (Eigen::Vector3d(a, b, c) - Eigen::Vector3d::Constant(1.5)) * (spacing / 4);
          inside += (x + o).norm() <= r;
        }
    return float(inside) / 64.0f;
  });
}

}  // namespace fluoro::test
