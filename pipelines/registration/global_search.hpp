#pragma once
// A global initialisation for starts too far off for the contour ICP (issue 14: far starts with
// automatic contours). The bone is turned about its centre through a grid of rotations; for
// each rotation, every view's bone DRR is cross-correlated with the X-ray (their x and y
// derivatives, by FFT, over every image-plane shift at once), and the shifts the views ask for
// are solved for one 3D translation. A hypothesis scores the views' correlations at the shifts
// that translation actually makes, so views that disagree about where the bone is score low.
//
// The grid's best hypotheses are then refined by finer turns about themselves (Refinement).
//
// It works on small images (about 128 pixels a side, the grid's fewer for a coarse CT; rays sampled
// every 3 mm), so a search over ~120 rotations and three views costs a few hundred small DRRs in
// one backend batch (and its refinement, two batches a level, about half as many more): it is run
// only when the contour ICP from the start does not correlate like a registered pose.
#include <optional>
#include <span>
#include <vector>

#include <opencv2/core.hpp>

#include "engine/backend.hpp"
#include "engine/camera.hpp"
#include "engine/image.hpp"
#include "engine/pose.hpp"

namespace fluoro {

struct GlobalSearchOptions {
  double max_rotation_deg = 45.0;  // rotations (about the bone centre) within this angle of the start...
  double rotation_step_deg = 15.0;  // ...on a grid of rotation vectors this fine
  int max_side = 128;               // working image size (pixels, the larger side)
  // The grid's views are reduced further while a working pixel at the views' isocentre still holds
  // no more than one of the CT's voxels (correlation_reductions with this many pixels a voxel; the
  // refinement keeps max_side): with C-arm views of 0.36 to 0.48 mm pixels at the isocentre, 64^2
  // on a CT of 3 mm voxels and 96^2 to 102^2 on 2 mm. Not positive: the grid works at max_side too.
  double grid_pixels_per_voxel = 1.0;
  double step_mm = 3.0;             // ray sampling step of the search's DRRs
  double blur_px = 1.0;             // Gaussian smoothing before differentiating (working pixels)
  double max_shift_fraction = 0.45;  // image-plane shifts searched, as a fraction of the image side
  int candidates = 8;               // hypotheses returned, best first
  // Then, level by level, each of the best Refinement::candidates hypotheses is turned by step_deg
  // either way about each axis (about its bone centre), then by the vertex of the three scores'
  // parabola about every axis at once, and replaced by the best of itself (re-scored) and those;
  // all are sorted again. Against the 26 neighbours of a step_deg grid about each of the best 4 (the
  // form before), 6 here found as many right poses on the far-start sweeps or more, in a third less
  // time; the second level's 2 candidates had given the same pelvis-CT far starts as 4.
  struct Refinement {
    int candidates = 0;
    double step_deg = 0;
  };
  std::vector<Refinement> refinements{{6, 5.0}, {2, 2.0}};
};

// Where the parabola through the scores at -1, 0 and +1 step peaks, in steps, within [-1, 1]; where
// the scores do not bend down, the better end if it beats the middle, else 0. The refinement's turn
// about each axis.
double parabola_vertex(double minus, double zero, double plus);

struct GlobalHypothesis {
  Pose pose;             // T_world_ct
  double score = 0;      // mean over views of the derivative correlation at the solved shift
};

class GlobalSearch {
 public:
  // One X-ray per camera (log domain, bone dark), at full size; reduced here. voxel_mm: the CT's
  // finest voxel spacing (0: unknown, the grid works at max_side).
  GlobalSearch(std::span<const PinholeCamera> cameras, std::span<const Image> xrays, GlobalSearchOptions options = {},
               double voxel_mm = 0);

  // The best `candidates` hypotheses for a start `initial`, whose bone centre (CT coordinates)
  // is `centre_ct`; `bone_mu` is the bone-only attenuation the DRRs are rendered from.
  std::vector<GlobalHypothesis> search(Backend& backend, const DeviceVolume& bone_mu, const Pose& initial,
                                       const Eigen::Vector3d& centre_ct) const;

  // The rotation vectors (radians) tried: the grid points within max_rotation_deg, the zero one first.
  std::vector<Eigen::Vector3d> rotations() const;

  // Per view, the factor the grid's views are reduced by (the refinement's: size_reduction(max_side)).
  const std::vector<int>& grid_reductions() const { return grid_factors_; }

 private:
  struct View {
    PinholeCamera camera;  // reduced
    cv::Mat spectrum[2];   // DFT of the X-ray's minus-derivatives (x, y), normalised, zero-padded
  };
  // The views reduced to one working size, with what their correlations need.
  struct Scale {
    std::vector<View> views;
    cv::Size padded;
    int max_shift = 0;  // pixels, either axis
  };
  // The hypotheses from each start turned by each rotation vector about the start's bone centre
  // (start-major: start s, rotation r at s * rotations + r), unsorted, from one backend batch.
  std::vector<GlobalHypothesis> score_rotations(const Scale& scale, Backend& backend, const DeviceVolume& bone_mu,
                                                std::span<const Pose> starts,
                                                const Eigen::Vector3d& centre_ct,
                                                std::span<const Eigen::Vector3d> rotation_vectors) const;

  // One refinement level about each of `hypotheses`, each replaced in place by the best pose seen.
  void refine(Backend& backend, const DeviceVolume& bone_mu, const Eigen::Vector3d& centre_ct, double step_deg,
              std::span<GlobalHypothesis> hypotheses) const;

  static Scale make_scale(std::span<const PinholeCamera> cameras, std::span<const Image> xrays, std::span<const int> factors,
                          const GlobalSearchOptions& options);
  const Scale& grid_scale() const { return grid_ ? *grid_ : scale_; }

  GlobalSearchOptions options_;
  Scale scale_;                 // the refinement's, max_side
  std::optional<Scale> grid_;   // the grid's, where coarser (grid_pixels_per_voxel)
  std::vector<int> grid_factors_;
};

}  // namespace fluoro
