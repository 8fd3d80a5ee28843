#include "engine/point_list_io.hpp"

#include <cmath>
#include <nlohmann/json.hpp>

#include "engine/error.hpp"
#include "engine/json_io.hpp"

namespace fluoro {
namespace {

using nlohmann::json;

template <int N>
std::vector<std::optional<Eigen::Matrix<double, N, 1>>> read_points(const std::string& path) {
  const json doc = read_json(path);
  if (!doc.is_object() || !doc.contains("points") || !doc["points"].is_array())
    throw_input_error(path, "expected {\"points\": [[...], ...]}");
  std::vector<std::optional<Eigen::Matrix<double, N, 1>>> out;
  for (const json& p : doc["points"]) {
    const std::string at = "point " + std::to_string(out.size());
    if (p.is_null()) {
      out.emplace_back();
      continue;
    }
    if (!p.is_array() || p.size() != size_t(N))
      throw_input_error(path, at + " must be an array of " + std::to_string(N) + " numbers or null");
    Eigen::Matrix<double, N, 1> v;
    for (int i = 0; i < N; ++i) {
      if (!p[size_t(i)].is_number()) throw_input_error(path, at + " has a coordinate that is not a number");
      v[i] = p[size_t(i)].get<double>();
    }
    if (!v.allFinite()) throw_input_error(path, at + " is not finite");
    out.emplace_back(v);
  }
  return out;
}

template <class List>
void write_points(const List& points, const std::string& path) {
  json list = json::array();
  for (const auto& p : points) {
    if (!p) {
      list.push_back(nullptr);
      continue;
    }
    json coords = json::array();
    for (int i = 0; i < p->size(); ++i) coords.push_back((*p)[i]);
    list.push_back(std::move(coords));
  }
  write_json(json{{"points", std::move(list)}}, path);
}

}  // namespace

PointList2 read_points_2d(const std::string& path) { return read_points<2>(path); }
PointList3 read_points_3d(const std::string& path) { return read_points<3>(path); }

std::vector<Eigen::Vector3d> read_complete_points_3d(const std::string& path) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : read_points_3d(path)) {
    if (!p) throw_input_error(path, "point " + std::to_string(out.size()) + " is null; every point must be given here");
    out.push_back(*p);
  }
  return out;
}

void write_points_2d(const PointList2& points, const std::string& path) { write_points(points, path); }
void write_points_3d(const PointList3& points, const std::string& path) { write_points(points, path); }

}  // namespace fluoro
