#pragma once
// Paired-point (landmark, contact) registration with its error analysis: the registration
// pipeline's Horn solution, its fiducial registration error (FRE) and the Fitzpatrick-West
// prediction of the target registration error (TRE) at given targets.
#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "engine/pose.hpp"

namespace fluoro {

// T_fixed_moving with FRE (RMS and largest 3D residual), the FLE the prediction used (given, or
// estimated from FRE) and the predicted RMS TRE per target. ok = false with a reason when the
// points are too few or (nearly) collinear in either frame: the rotation is then undetermined.
struct PairedRegistration {
  bool ok = false;
  std::string failure_reason;
  Pose T_fixed_moving = Pose::Identity();
  double fre_rms_mm = 0, fre_max_mm = 0;
  double fle_rms_mm = 0;
  bool fle_estimated = false;  // from FRE: FLE^2 = FRE^2 N / (N - 2)
  std::vector<double> predicted_tre_rms_mm;
};

// fixed[i] and moving[i] are the same point in two frames (sizes must match: the caller checks);
// targets are in the moving frame. Without fle_rms_mm, the FLE is estimated from the FRE.
// `weights` (empty: all equal; else one positive weight per pair, the caller checks) weight the
// Horn solution; a weight is taken as 1 / FLE_i^2 up to scale, each fiducial's FLE scaled so that
// their RMS is the FLE, and the TRE predicted by first-order propagation
// (predicted_tre_rms_weighted); with equal weights that is Fitzpatrick-West's formula.
PairedRegistration register_paired_points(const std::vector<Eigen::Vector3d>& fixed,
                                          const std::vector<Eigen::Vector3d>& moving,
                                          const std::vector<Eigen::Vector3d>& targets,
                                          std::optional<double> fle_rms_mm, const std::vector<double>& weights = {});

// A reason why these points cannot fix a rotation (fewer than 3, or within 0.1 % of their extent
// of one line), or "" when they can.
std::string rotation_degeneracy(const std::vector<Eigen::Vector3d>& points);

}  // namespace fluoro
