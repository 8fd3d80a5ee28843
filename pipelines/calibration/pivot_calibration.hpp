#pragma once
// Pivot calibration of a tracked pointer: the tool pivots about its tip held still in a divot;
// one linear least-squares problem gives the tip in the tool's frame and the pivot in the
// tracker's frame together (R_i tip + p_i = pivot for every pose i).
#include <Eigen/Core>
#include <algorithm>
#include <string>
#include <vector>

#include "engine/pose.hpp"

namespace fluoro {

// What decides that the poses cannot determine the tip (the result is then a failure, never a guess).
struct PivotParams {
  size_t min_poses = 3;                  // two poses always leave the tip free along their relative axis
  double min_rotation_spread_deg = 10;   // see PivotCalibration::rotation_spread_deg
};

// Below this spread the tip is not determined whatever PivotParams says (a --min-rotation-deg of 0
// must not turn one-axis pivoting into a tip of NaN or 1e15 mm): 0.01 deg multiplies the tracker's
// noise by about 10^4 / sqrt(n).
constexpr double kUndeterminedRotationSpreadDeg = 0.01;

// The spread a pivot calibration with these parameters needs: the larger of the two above.
inline double least_rotation_spread_deg(const PivotParams& params) {
  return std::max(params.min_rotation_spread_deg, kUndeterminedRotationSpreadDeg);
}

// The tip and pivot with the RMS and largest 3D distance between R_i tip + p_i and the pivot.
// ok = false with a reason when the poses are too few or too little rotated (no tip/pivot then).
struct PivotCalibration {
  bool ok = false;
  std::string failure_reason;
  Eigen::Vector3d tip_in_tool = Eigen::Vector3d::Zero();
  Eigen::Vector3d pivot_in_tracker = Eigen::Vector3d::Zero();
  double rms_mm = 0, max_mm = 0;
  // 2 asin(sigma_min(A) / sqrt(n)) of the stacked system A = [R_i, -I]: the swing angle of a
  // symmetric pivoting about two axes, 0 when all rotations share one axis (the tip's component
  // along it is then undetermined). The tip's error grows as noise / (sin(spread/2) sqrt(n)).
  double rotation_spread_deg = 0;
  size_t poses = 0;
};

// T_tracker_tool of every pose. Poses must be rigid (the caller validates the file).
PivotCalibration pivot_calibration(const std::vector<Pose>& tracker_from_tool, const PivotParams& params = {});

}  // namespace fluoro
