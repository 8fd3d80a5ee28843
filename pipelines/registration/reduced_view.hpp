#pragma once
// An X-ray and its camera reduced by an integer factor, so that neither side exceeds a size: the
// gradient correlation judges poses on about 256 pixels a side, the global search on about 128.
// Whole f x f blocks are averaged (the last partial row or column of blocks is dropped), and the
// camera's intrinsics are scaled to match, so a DRR rendered with the reduced camera lines up with
// the reduced image pixel for pixel.
#include <opencv2/core.hpp>
#include <vector>

#include "engine/camera.hpp"
#include "engine/image.hpp"

namespace fluoro {

struct ReducedView {
  PinholeCamera camera;
  cv::Mat image;  // CV_32F, camera.height x camera.width
  int factor = 1;
};

// The smallest integer factor that brings the larger side to at most max_side pixels.
int size_reduction(const PinholeCamera& camera, int max_side);

// The image and camera reduced by `factor` (at least 1).
ReducedView reduce_view_by(const PinholeCamera& camera, const Image& image, int factor);

// reduce_view_by(camera, image, size_reduction(camera, max_side)).
ReducedView reduce_view(const PinholeCamera& camera, const Image& image, int max_side);

// Per view, the gradient correlation's reduction: size_reduction(max_side), or more where even the
// reduced pixels would resolve the CT finer than it holds. A DRR of a CT with voxel_mm voxels has
// no detail finer than those voxels' outlines, so the factor grows while a reduced pixel at the
// views' isocentre (the point nearest to their principal rays, where C-arm views converge and the
// bone lies) still cuts voxel_mm into min_pixels_per_voxel pixels or more, along the coarser pixel
// axis; the reduced side stays at least min_side pixels. Why: on the shared pelvis CT (3 mm voxels)
// with 512^2 views of 0.36 mm at the bone, the correlation's 256^2 DRRs sampled each voxel 4 times
// a side and took half the registration; at 2.5 pixels a voxel (170^2) that part took 0.32 s
// instead of 0.74 and the pose moved by 0.01 mm (docs/benchmarks.md, "The correlation's pixels by
// the CT's voxels"). Without an isocentre (principal rays under about a degree apart) every view
// keeps the size rule; a view with the isocentre behind its source keeps it alone; and every view
// keeps it when min_pixels_per_voxel is not positive.
std::vector<int> correlation_reductions(const std::vector<PinholeCamera>& cameras, double voxel_mm, int max_side,
                                        double min_pixels_per_voxel, int min_side);

}  // namespace fluoro
