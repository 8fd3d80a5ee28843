#pragma once
// The dewarp plate, GRID.json (shared/docs/FORMATS.md): holes on a square lattice fixed to the image
// intensifier. Hole (r, c) lies at plate coordinates ((c - (cols-1)/2) pitch, (r - (rows-1)/2) pitch) mm.
#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <string>

namespace fluoro {

struct GridModel {
  double pitch_mm = 10.0;
  double hole_diameter_mm = 3.0;
  int rows = 25;
  int cols = 25;
  double thickness_mm = 7.0;

  // Plate coordinates (mm, on the plate's mid-plane) of hole (r, c); r and c may be fractional.
  Eigen::Vector2d hole_mm(double r, double c) const {
    return {(c - 0.5 * (cols - 1)) * pitch_mm, (r - 0.5 * (rows - 1)) * pitch_mm};
  }
};

// Throws InputError naming the path for a missing file, bad JSON, a "kind" other than "hole_grid",
// or a non-positive / non-finite size (holes must be narrower than the pitch).
GridModel read_grid_model(const std::string& path);
nlohmann::json grid_model_to_json(const GridModel& grid);

}  // namespace fluoro
