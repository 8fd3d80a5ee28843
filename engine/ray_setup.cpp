#include "engine/ray_setup.hpp"

namespace fluoro {

RaySetup make_ray_setup(const VolumeGeometry& g, const Pose& T_world_ct, const PinholeCamera& cam) {
  const Pose T_ct_world = T_world_ct.inverse();
  const Eigen::Matrix3d ct_to_index =
      g.spacing.cwiseInverse().asDiagonal() * g.direction.transpose();
  const Eigen::Matrix3d kinv = cam.K.inverse();
  const Eigen::Matrix3d cam_to_ct = T_ct_world.rotation() * cam.R.transpose();

  RaySetup s;
  s.source = g.physical_to_index(T_ct_world * cam.source());
  s.pixel_to_dir = ct_to_index * cam_to_ct * kinv;
  s.kinv = kinv;
  s.axis_u = cam_to_ct * kinv.col(0);
  s.axis_v = cam_to_ct * kinv.col(1);
  s.box_hi = g.size.cast<double>() - Eigen::Vector3d::Constant(0.5);
  return s;
}

}  // namespace fluoro
