#pragma once
// How far a registration is from the truth, in the measures the 2D/3D registration literature
// reports: target registration error over the bone surface and at fiducials, the mean projection
// distance on the detector, and the rotation and translation of the error transform.
#include <Eigen/Core>
#include <vector>

#include "engine/camera.hpp"
#include "engine/pose.hpp"
#include "engine/volume.hpp"

namespace fluoro {

struct RegistrationErrors {
  double surface_tre_mean_mm = 0, surface_tre_max_mm = 0;  // over the surface points
  double fiducial_tre_mean_mm = 0;                          // NaN without fiducials
  double mpd_mm = 0;         // mean projection distance on the detector (NaN without pixel spacing)
  double rotation_deg = 0;   // of the error transform estimate * truth^-1
  double translation_mm = 0;
};

// Errors of T_world_ct `estimate` against `truth`. Points are in the CT frame; the mean projection
// distance averages, over views and surface points, the detector distance (pixel_spacing_mm)
// between the points projected at both poses.
RegistrationErrors registration_errors(const Pose& estimate, const Pose& truth,
                                       const std::vector<Eigen::Vector3d>& surface_points,
                                       const std::vector<Eigen::Vector3d>& fiducials,
                                       const std::vector<PinholeCamera>& views);

// Points on a bone surface for the errors above: centres of voxels at or above `iso_hu` with a
// 6-neighbour below it, an evenly spread subset of at most max_points, in the CT frame.
std::vector<Eigen::Vector3d> surface_points(const Volume& hu, double iso_hu, size_t max_points);

// The mean of the points (zero for none): the bone centre rotations turn about.
Eigen::Vector3d mean_point(const std::vector<Eigen::Vector3d>& points);

}  // namespace fluoro
