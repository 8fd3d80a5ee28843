#pragma once
// Coarse geometry-based registration (seed, chapter 2, section V): 2D/3D ICP that moves the bone
// surface mesh until the rays from each X-ray source through the bone's contour pixels are
// tangent to it, i.e. pass through its apparent contour. Each iteration pairs rays with apparent
// contour points (nearest in the image, an exact distance transform), drops outlier pairs, and
// takes a Gauss-Newton step on the sum of squared 3D ray-to-point distances.
#include <span>
#include <vector>

#include "engine/camera.hpp"
#include "engine/pose.hpp"
#include "pipelines/registration/bone_mesh.hpp"

namespace fluoro {

enum class ContourMatching {
  // Each contour pixel's ray to its closest apparent-contour point: for contours a user traced
  // (clean, but maybe only part of the bone).
  contour_to_mesh,
  // Each apparent-contour point to its closest contour pixel's ray: for edges found
  // automatically (the whole bone, but with clutter from other anatomy and tools).
  mesh_to_contour,
};

// One X-ray's bone contour: pixels and, where known, the unit image-gradient direction at each
// (used to pair a pixel only with mesh contour running the same way).
struct ContourData {
  PinholeCamera camera;
  std::vector<Eigen::Vector2f> pixels;
  std::vector<Eigen::Vector2f> normals;  // empty, or one per pixel
  ContourMatching matching = ContourMatching::mesh_to_contour;
};

struct ContourIcpOptions {
  int max_iterations = 100;
  // Pairs further apart than max(min_inlier_mm, inlier_factor * median distance) are outliers.
  double inlier_factor = 2.5;
  double min_inlier_mm = 2.0;
  // With normals: pair only where |cos| between the contour's and the projected mesh contour's
  // normals reaches this.
  double normal_agreement = 0.5;
  // Stop when an iteration moves the mesh by less than this (mm, at its typical radius).
  double tolerance_mm = 0.1;
};

struct ContourIcpResult {
  Pose pose;               // T_world_ct
  int iterations = 0;
  double rms_mm = 0;       // ray-to-point distance over the last iteration's inlier pairs
  double median_mm = 0;    // median over all its pairs
  int pairs = 0, inliers = 0;
  bool converged = false;
};

// Throws InputError when a view has no contour pixels, or when no view yields a pair at the
// initial pose (the bone projects outside every image).
ContourIcpResult register_contours(const BoneMesh& mesh, std::span<const ContourData> views, const Pose& initial,
                                   const ContourIcpOptions& options = {});

}  // namespace fluoro
