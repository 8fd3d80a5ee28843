#pragma once
// Fitzpatrick, West and Maurer (1998): the expected target registration error of a point-based
// rigid registration from the fiducials' layout and the fiducial localisation error (FLE).
#include <Eigen/Core>
#include <vector>

namespace fluoro {

// RMS TRE at `target` (same frame as the fiducials): TRE^2 = FLE^2/N (1 + 1/3 sum_k d_k^2/f_k^2),
// d_k the target's distance from the fiducials' k-th principal axis, f_k the RMS distance of the
// fiducials from it, fle_rms_mm the RMS 3D FLE (isotropic, equal for every fiducial).
double predicted_tre_rms(const std::vector<Eigen::Vector3d>& fiducials, const Eigen::Vector3d& target, double fle_rms_mm);

// The same for a weighted registration (weights w_i, fiducial i's RMS 3D FLE fle_rms_mm[i],
// isotropic): first-order error propagation through the weighted least-squares pose (the normal
// equations of the small rotation and translation), RMS TRE = sqrt(trace(B Cov B^T)) at the target.
// With equal weights and FLEs it equals the formula above. Infinity for collinear fiducials.
double predicted_tre_rms_weighted(const std::vector<Eigen::Vector3d>& fiducials, const std::vector<double>& weights,
                                  const std::vector<double>& fle_rms_mm, const Eigen::Vector3d& target);

// The RMS FLE implied by an observed RMS FRE of n fiducials: <FRE^2> = (1 - 2/n) FLE^2 (same paper);
// n >= 3.
double fle_from_fre(double fre_rms_mm, size_t n);

}  // namespace fluoro
