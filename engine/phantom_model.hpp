#pragma once
// A calibration phantom, PHANTOM.json (shared/docs/FORMATS.md): steel balls at known positions in
// the phantom's frame, which becomes the world frame of the camera that calibration estimates.
#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace fluoro {

struct Fiducial {
  std::string id;
  Eigen::Vector3d position_mm;
};

struct PhantomModel {
  double fiducial_diameter_mm = 3.0;
  std::vector<Fiducial> fiducials;
};

// Throws InputError naming the path for a missing file, bad JSON, a "kind" other than
// "fiducial_phantom", a non-finite position, duplicate ids, fewer than 6 fiducials, or fiducials
// that are all coplanar (a camera cannot be calibrated from one plane in one image).
PhantomModel read_phantom_model(const std::string& path);
nlohmann::json phantom_model_to_json(const PhantomModel& phantom);

}  // namespace fluoro
