#pragma once
// The initial pose from landmarks (seed, chapter 2, section V, option 4): anatomical points the
// user picked on the CT and on two or more X-rays. Each landmark's X-ray pixels are triangulated
// from the camera rays, and the CT points are registered to them with weighted Horn.
#include <optional>
#include <string>
#include <vector>

#include "engine/camera.hpp"
#include "pipelines/registration/point_registration.hpp"

namespace fluoro {

struct Landmark {
  std::string name;
  Eigen::Vector3d ct;                                // CT frame, mm
  std::vector<std::optional<Eigen::Vector2d>> pixels;  // per view; empty where not visible
  double weight = 1.0;
};

// Reads {"landmarks": [{"name": "...", "ct": [x, y, z], "pixels": [[u, v] or null, ...],
// "weight": w}]}, one pixels entry per view. Throws InputError naming the file for a malformed
// document or a pixels list whose length is not `views`.
std::vector<Landmark> read_landmarks(const std::string& path, size_t views);

struct LandmarkRegistration {
  PointRegistration registration;        // transform: T_world_ct
  std::vector<double> ray_distance_mm;   // per landmark: how consistent its X-ray picks are
};

// Landmarks seen in fewer than two views are skipped; each triangulated point's weight is its
// own weight divided by (1 mm^2 + its rays' RMS distance^2), so inconsistent picks count less.
// Throws InputError naming `what` when fewer than three landmarks remain.
LandmarkRegistration register_landmarks(const std::vector<Landmark>& landmarks,
                                        const std::vector<PinholeCamera>& cameras, const std::string& what);

}  // namespace fluoro
