#include "pipelines/registration/landmarks.hpp"

#include <cmath>

#include "engine/error.hpp"
#include "engine/json_io.hpp"
#include "pipelines/registration/triangulation.hpp"

namespace fluoro {
namespace {

double number(const nlohmann::json& v, const std::string& path, const std::string& what) {
  if (!v.is_number() || !std::isfinite(v.get<double>())) throw_input_error(path, what + " must be a finite number");
  return v.get<double>();
}

}  // namespace

std::vector<Landmark> read_landmarks(const std::string& path, size_t views) {
  const nlohmann::json doc = read_json(path);
  if (!doc.is_object() || !doc.contains("landmarks") || !doc["landmarks"].is_array())
    throw_input_error(path, "expected {\"landmarks\": [...]}");
  std::vector<Landmark> out;
  for (const auto& item : doc["landmarks"]) {
    const std::string at = "landmark " + std::to_string(out.size() + 1);
    if (!item.is_object() || !item.contains("ct") || !item["ct"].is_array() || item["ct"].size() != 3)
      throw_input_error(path, at + ": \"ct\" must be [x, y, z]");
    Landmark l;
    l.name = item.value("name", at);
    for (int i = 0; i < 3; ++i) l.ct[i] = number(item["ct"][size_t(i)], path, at + " ct");
    if (!item.contains("pixels") || !item["pixels"].is_array() || item["pixels"].size() != views)
      throw_input_error(path, at + ": \"pixels\" must list one [u, v] (or null) per view (" + std::to_string(views) + ")");
    for (const auto& p : item["pixels"]) {
      if (p.is_null()) {
        l.pixels.emplace_back();
        continue;
      }
      if (!p.is_array() || p.size() != 2) throw_input_error(path, at + ": a pixel must be [u, v] or null");
      l.pixels.emplace_back(Eigen::Vector2d(number(p[0], path, at + " pixel"), number(p[1], path, at + " pixel")));
    }
    if (item.contains("weight")) {
      l.weight = number(item["weight"], path, at + " weight");
      if (l.weight < 0) throw_input_error(path, at + ": weight must not be negative");
    }
    out.push_back(std::move(l));
  }
  return out;
}

LandmarkRegistration register_landmarks(const std::vector<Landmark>& landmarks,
                                        const std::vector<PinholeCamera>& cameras, const std::string& what) {
  std::vector<Eigen::Vector3d> ct, world;
  std::vector<double> weights;
  LandmarkRegistration out;
  for (const Landmark& l : landmarks) {
    std::vector<PinholeCamera> cams;
    std::vector<Eigen::Vector2d> px;
    for (size_t v = 0; v < l.pixels.size() && v < cameras.size(); ++v)
      if (l.pixels[v]) {
        cams.push_back(cameras[v]);
        px.push_back(*l.pixels[v]);
      }
    if (cams.size() < 2) continue;
    const Triangulation t = triangulate(cams, px, what + ": landmark " + l.name);
    ct.push_back(l.ct);
    world.push_back(t.point);
    weights.push_back(l.weight / (1.0 + t.rms_ray_distance_mm * t.rms_ray_distance_mm));
    out.ray_distance_mm.push_back(t.rms_ray_distance_mm);
  }
  if (ct.size() < 3)
    throw_input_error(what, std::to_string(ct.size()) + " landmarks seen in two or more views; at least 3 are needed");
  out.registration = register_points(ct, world, weights, what);
  return out;
}

}  // namespace fluoro
