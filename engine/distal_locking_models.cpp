// Readers and writers of the distal-locking model files: GUIDE.json, NAIL.json and ROBOT.json.
#include "engine/distal_locking_models.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>

#include "engine/error.hpp"
#include "engine/json_io.hpp"
#include "engine/pose.hpp"

namespace fluoro {
namespace {

using nlohmann::json;


const json& require(const json& doc, const char* key, const std::string& path) {
  if (!doc.is_object() || !doc.contains(key)) throw_input_error(path, std::string("missing key \"") + key + "\"");
  return doc[key];
}

double positive(const json& doc, const char* key, const std::string& path) {
  const json& v = require(doc, key, path);
  if (!v.is_number() || !std::isfinite(v.get<double>()) || !(v.get<double>() > 0))
    throw_input_error(path, std::string("\"") + key + "\" must be a positive number");
  return v.get<double>();
}

Eigen::Vector3d vec3(const json& v, const std::string& what, const std::string& path) {
  if (!v.is_array() || v.size() != 3) throw_input_error(path, what + " must be an array of 3 numbers");
  Eigen::Vector3d out;
  for (int i = 0; i < 3; ++i) {
    if (!v[size_t(i)].is_number() || !std::isfinite(v[size_t(i)].get<double>()))
      throw_input_error(path, what + " must be an array of 3 finite numbers");
    out[i] = v[size_t(i)].get<double>();
  }
  return out;
}

Eigen::Isometry3d rigid(const json& doc, const char* key, const std::string& path) {
  const json& v = require(doc, key, path);
  const std::string bad = std::string("\"") + key + "\" must be a 4x4 array of numbers";
  if (!v.is_array() || v.size() != 4) throw_input_error(path, bad);
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    if (!v[size_t(r)].is_array() || v[size_t(r)].size() != 4) throw_input_error(path, bad);
    for (int c = 0; c < 4; ++c) {
      const json& e = v[size_t(r)][size_t(c)];
      if (!e.is_number()) throw_input_error(path, bad);
      m(r, c) = e.get<double>();
    }
  }
  return pose_from_matrix(m, path + " (" + key + ")");
}

json rows(const Eigen::Matrix4d& m) {
  json out = json::array();
  for (int r = 0; r < 4; ++r) out.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return out;
}

}  // namespace

DrillGuideModel read_drill_guide_model(const std::string& path) {
  const json doc = read_json_of_kind(path, "drill_guide");
  DrillGuideModel g;
  g.sphere_diameter_mm = positive(doc, "sphere_diameter_mm", path);
  const json& spheres = require(doc, "spheres_mm", path);
  if (!spheres.is_array()) throw_input_error(path, "\"spheres_mm\" must be an array of [x, y, z]");
  for (size_t i = 0; i < spheres.size(); ++i)
    g.spheres_mm.push_back(vec3(spheres[i], "spheres_mm[" + std::to_string(i) + "]", path));
  if (g.spheres_mm.size() < 6)
    throw_input_error(path, "a drill guide needs at least 6 spheres, this one has " + std::to_string(g.spheres_mm.size()));
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : g.spheres_mm) mean += p;
  mean /= double(g.spheres_mm.size());
  Eigen::Matrix3d s = Eigen::Matrix3d::Zero();
  for (const auto& p : g.spheres_mm) s += (p - mean) * (p - mean).transpose();
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(s).eigenvalues();
  if (ev(0) <= 1e-6 * ev(2)) throw_input_error(path, "the spheres all lie in one plane: one image cannot fix the guide's pose");
  const json& axes = require(doc, "axes", path);
  if (!axes.is_array()) throw_input_error(path, "\"axes\" must be an array");
  for (size_t i = 0; i < axes.size(); ++i) {
    const std::string what = "axes[" + std::to_string(i) + "]";
    GuideAxis a;
    a.name = axes[i].contains("name") && axes[i]["name"].is_string() ? axes[i]["name"].get<std::string>() : what;
    a.point_mm = vec3(require(axes[i], "point_mm", path), what + ".point_mm", path);
    a.direction = vec3(require(axes[i], "direction", path), what + ".direction", path);
    if (a.direction.norm() < 1e-9) throw_input_error(path, what + ".direction is zero");
    a.direction.normalize();
    g.axes.push_back(a);
  }
  return g;
}

json drill_guide_model_to_json(const DrillGuideModel& g) {
  json spheres = json::array(), axes = json::array();
  for (const auto& p : g.spheres_mm) spheres.push_back({p.x(), p.y(), p.z()});
  for (const auto& a : g.axes)
    axes.push_back({{"name", a.name},
                    {"point_mm", {a.point_mm.x(), a.point_mm.y(), a.point_mm.z()}},
                    {"direction", {a.direction.x(), a.direction.y(), a.direction.z()}}});
  return {{"kind", "drill_guide"}, {"sphere_diameter_mm", g.sphere_diameter_mm}, {"spheres_mm", spheres}, {"axes", axes}};
}

NailModel read_nail_model(const std::string& path) {
  const json doc = read_json_of_kind(path, "nail");
  NailModel n;
  n.diameter_mm = positive(doc, "diameter_mm", path);
  const json& holes = require(doc, "holes", path);
  if (!holes.is_array() || holes.empty()) throw_input_error(path, "\"holes\" must be a non-empty array");
  for (size_t i = 0; i < holes.size(); ++i) {
    const std::string what = "holes[" + std::to_string(i) + "]";
    NailHole h;
    h.center_mm = vec3(require(holes[i], "center_mm", path), what + ".center_mm", path);
    h.diameter_mm = positive(holes[i], "diameter_mm", path);
    if (std::abs(h.center_mm.y()) > 0.01 || std::abs(h.center_mm.z()) > 0.01)
      throw_input_error(path, what + " is not on the nail: its centre must lie on the nail's long axis (y = z = 0)");
    if (h.diameter_mm >= n.diameter_mm) throw_input_error(path, what + " is not narrower than the nail");
    for (const auto& o : n.holes)
      if (std::abs(o.center_mm.x() - h.center_mm.x()) < 0.5 * (o.diameter_mm + h.diameter_mm))
        throw_input_error(path, what + " overlaps another hole");
    n.holes.push_back(h);
  }
  return n;
}

json nail_model_to_json(const NailModel& n) {
  json holes = json::array();
  for (const auto& h : n.holes)
    holes.push_back({{"center_mm", {h.center_mm.x(), h.center_mm.y(), h.center_mm.z()}}, {"diameter_mm", h.diameter_mm}});
  return {{"kind", "nail"}, {"diameter_mm", n.diameter_mm}, {"holes", holes}};
}

RobotModel read_robot_model(const std::string& path) {
  json doc = read_json(path);
  if (!doc.is_object()) throw_input_error(path, "expected a JSON object at the top level");
  return {rigid(doc, "T_base_tip", path), rigid(doc, "T_tip_guide", path)};
}

json robot_model_to_json(const RobotModel& r) {
  return {{"T_base_tip", rows(r.T_base_tip.matrix())}, {"T_tip_guide", rows(r.T_tip_guide.matrix())}};
}

}  // namespace fluoro
