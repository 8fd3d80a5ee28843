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

// Whether a given FLE can explain the registration's residuals: with isotropic Gaussian
// localisation errors of RMS 3D size FLE_i, sum_i |e_i|^2 / (FLE_i^2 / 3) follows chi^2 with
// 3N - 6 degrees of freedom. Beyond its 99.9 % quantile the given FLE is too small for what the
// points show, and a TRE predicted with it is optimistic (a wrong --fle-mm, a swapped or moved
// fiducial). Only the upper tail is tested: an FLE larger than the residuals show errs on the safe
// side.
struct FleCheck {
  double fle_from_residuals_mm = 0;  // the FLE that makes the statistic its mean (3N - 6): FLE^2 = FRE^2 N / (N - 2) unweighted
  double chi2 = 0, chi2_limit = 0;   // the statistic with the given FLE, and its 99.9 % quantile
  bool consistent = true;            // chi2 <= chi2_limit
  std::vector<double> predicted_tre_rms_mm;  // with fle_from_residuals_mm, at the same targets
};

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
  // The given FLE against the residuals (FleCheck); empty when the FLE was estimated from them.
  std::optional<FleCheck> fle_check;
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
