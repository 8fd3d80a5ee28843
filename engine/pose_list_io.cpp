#include "engine/pose_list_io.hpp"

#include <nlohmann/json.hpp>

#include "engine/error.hpp"
#include "engine/json_io.hpp"

namespace fluoro {

std::vector<Pose> read_pose_list(const std::string& path, const std::string& key) {
  const nlohmann::json doc = read_json(path);
  if (!doc.is_object() || !doc.contains(key) || !doc[key].is_array())
    throw_input_error(path, "expected {\"" + key + "\": [4x4 matrix, ...]}");
  std::vector<Pose> poses;
  for (const nlohmann::json& m : doc[key]) {
    const std::string what = path + ": pose " + std::to_string(poses.size());
    Eigen::Matrix4d matrix;
    const auto bad = [&]() { throw_input_error(what, "must be a 4x4 array of numbers"); };
    if (!m.is_array() || m.size() != 4) bad();
    for (int r = 0; r < 4; ++r) {
      if (!m[size_t(r)].is_array() || m[size_t(r)].size() != 4) bad();
      for (int c = 0; c < 4; ++c) {
        if (!m[size_t(r)][size_t(c)].is_number()) bad();
        matrix(r, c) = m[size_t(r)][size_t(c)].get<double>();
      }
    }
    poses.push_back(pose_from_matrix(matrix, what));
  }
  return poses;
}

}  // namespace fluoro
