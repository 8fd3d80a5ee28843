#pragma once
// Pairing of detected ball centres with a phantom's fiducials, from the pattern's asymmetry alone:
// hypothesise (a pose from 3 pairs by P3P under a family of focal lengths), verify (project every
// fiducial, pair it with the nearest detection, refit a DLT, count the pairs within a tolerance).
#include <Eigen/Core>
#include <optional>
#include <vector>

#include "pipelines/calibration/projection_dlt.hpp"

namespace fluoro {

// Tolerances of the verification. The tight one is what a pair must reach under the refitted DLT.
// A wrong pairing that a DLT can still explain leaves residuals near the tolerance; a right one
// leaves the detector's noise, so the rms of the pairs is bounded too.
struct MatchingParams {
  double tight_tolerance_px = 1.5;
  double max_rms_px = 0.5;
  double min_paired_fraction = 0.6;  // of min(fiducials, detections)
  int max_model_triples = 6;         // basis triples tried before giving up
};

// The best pairing: for each fiducial the index of its detection (-1 when unpaired), the DLT
// of the pairs, and how many pairs there are. Detections paired with no fiducial are clutter.
struct FiducialMatching {
  std::vector<int> detection_of;
  Projection P;
  int pairs = 0;
  double rms_px = 0;
};

// Why a search found nothing: set when a hypothesis paired 6 or more fiducials that all lie in one
// plane (one image of coplanar points cannot fix a projection, so no pairing could be verified).
struct MatchingDiagnostics {
  bool coplanar_pairs_seen = false;
};

// nullopt when no hypothesis pairs at least 6 fiducials and 60 % of min(fiducials, detections). The principal point is assumed near the
// image centre and the focal length between 1 and 6 image sizes (a C-arm's is 2.5 to 3.5) only to
// generate hypotheses; the verified pairing does not depend on them.
std::optional<FiducialMatching> match_fiducials(const std::vector<Eigen::Vector3d>& model,
                                                const std::vector<Eigen::Vector2d>& detections,
                                                int width, int height, const MatchingParams& params = {},
                                                MatchingDiagnostics* diagnostics = nullptr);

}  // namespace fluoro
