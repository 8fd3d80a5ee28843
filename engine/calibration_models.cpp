// Readers and writers of the calibration objects' model files: GRID.json and PHANTOM.json.
#include <Eigen/Eigenvalues>
#include <cmath>
#include <set>

#include "engine/error.hpp"
#include "engine/grid_model.hpp"
#include "engine/json_io.hpp"
#include "engine/phantom_model.hpp"

namespace fluoro {
namespace {

using nlohmann::json;


double positive_number(const json& doc, const char* key, const std::string& path, double fallback, bool required) {
  if (!doc.contains(key)) {
    if (required) throw_input_error(path, std::string("missing key \"") + key + "\"");
    return fallback;
  }
  const json& v = doc[key];
  if (!v.is_number() || !std::isfinite(v.get<double>()) || !(v.get<double>() > 0))
    throw_input_error(path, std::string("\"") + key + "\" must be a positive number");
  return v.get<double>();
}

int positive_count(const json& doc, const char* key, const std::string& path) {
  const double d = positive_number(doc, key, path, 0, true);
  if (d != std::floor(d) || d > 100000) throw_input_error(path, std::string("\"") + key + "\" must be a positive integer");
  return int(d);
}

}  // namespace

GridModel read_grid_model(const std::string& path) {
  const json doc = read_json_of_kind(path, "hole_grid");
  GridModel g;
  g.pitch_mm = positive_number(doc, "pitch_mm", path, 0, true);
  g.hole_diameter_mm = positive_number(doc, "hole_diameter_mm", path, 0, true);
  g.rows = positive_count(doc, "rows", path);
  g.cols = positive_count(doc, "cols", path);
  g.thickness_mm = positive_number(doc, "thickness_mm", path, g.thickness_mm, false);
  if (g.hole_diameter_mm >= g.pitch_mm) throw_input_error(path, "holes as wide as the pitch touch each other");
  if (g.rows < 3 || g.cols < 3) throw_input_error(path, "a grid needs at least 3 x 3 holes");
  return g;
}

json grid_model_to_json(const GridModel& g) {
  return {{"kind", "hole_grid"}, {"pitch_mm", g.pitch_mm}, {"hole_diameter_mm", g.hole_diameter_mm},
          {"rows", g.rows},      {"cols", g.cols},         {"thickness_mm", g.thickness_mm}};
}

PhantomModel read_phantom_model(const std::string& path) {
  const json doc = read_json_of_kind(path, "fiducial_phantom");
  PhantomModel p;
  p.fiducial_diameter_mm = positive_number(doc, "fiducial_diameter_mm", path, 0, true);
  if (!doc.contains("fiducials") || !doc["fiducials"].is_array())
    throw_input_error(path, "\"fiducials\" must be an array of {\"id\", \"position_mm\"}");
  std::set<std::string> ids;
  for (const json& f : doc["fiducials"]) {
    const std::string at = "fiducial " + std::to_string(p.fiducials.size());
    if (!f.is_object() || !f.contains("position_mm") || !f["position_mm"].is_array() || f["position_mm"].size() != 3)
      throw_input_error(path, at + ": expected {\"id\": ..., \"position_mm\": [x, y, z]}");
    Fiducial fid;
    // A missing id is the fiducial's index; a numeric one keeps its digits ("id": 7 is "7").
    if (!f.contains("id"))
      fid.id = std::to_string(p.fiducials.size());
    else if (f["id"].is_string())
      fid.id = f["id"].get<std::string>();
    else if (f["id"].is_number_integer())
      fid.id = f["id"].dump();
    else
      throw_input_error(path, at + ": \"id\" must be a string or an integer");
    for (int i = 0; i < 3; ++i) {
      const json& c = f["position_mm"][size_t(i)];
      if (!c.is_number()) throw_input_error(path, at + ": position_mm must hold 3 numbers");
      fid.position_mm[i] = c.get<double>();
    }
    if (!fid.position_mm.allFinite()) throw_input_error(path, at + ": position is not finite");
    if (!ids.insert(fid.id).second) throw_input_error(path, "duplicate fiducial id \"" + fid.id + "\"");
    p.fiducials.push_back(fid);
  }
  if (p.fiducials.size() < 6)
    throw_input_error(path, "a phantom needs at least 6 fiducials, got " + std::to_string(p.fiducials.size()));
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& f : p.fiducials) mean += f.position_mm;
  mean /= double(p.fiducials.size());
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  for (const auto& f : p.fiducials) spread += (f.position_mm - mean) * (f.position_mm - mean).transpose();
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(spread).eigenvalues();
  if (ev(0) <= 1e-9 * std::max(1.0, ev(2)))
    throw_input_error(path, "the fiducials are coplanar: one image of them cannot calibrate a camera");
  return p;
}

json phantom_model_to_json(const PhantomModel& p) {
  json list = json::array();
  for (const auto& f : p.fiducials)
    list.push_back({{"id", f.id}, {"position_mm", {f.position_mm.x(), f.position_mm.y(), f.position_mm.z()}}});
  return {{"kind", "fiducial_phantom"}, {"fiducial_diameter_mm", p.fiducial_diameter_mm}, {"fiducials", list}};
}

}  // namespace fluoro
