#pragma once
// Camera and pose JSON files (docs/conventions.md), validated on read; writes are atomic.
#include <nlohmann/json.hpp>
#include <string>

#include "engine/camera.hpp"
#include "engine/pose.hpp"

namespace fluoro {

// Accepts K, R, t or P (3x4) plus width, height and optional pixel_spacing_mm. Throws InputError
// naming the path for a missing file, bad JSON, wrong matrix sizes, singular K or improper R.
PinholeCamera read_camera(const std::string& path);
nlohmann::json camera_to_json(const PinholeCamera& camera);
void write_camera(const PinholeCamera& camera, const std::string& path);

// { "T_world_ct": 4x4 row-major }, checked to be a proper rigid transform.
Pose read_pose(const std::string& path);
nlohmann::json pose_to_json(const Pose& pose);
void write_pose(const Pose& pose, const std::string& path);

nlohmann::json read_json(const std::string& path);
// A model file: a JSON object whose "kind" is `kind`; InputError naming the path otherwise.
nlohmann::json read_json_of_kind(const std::string& path, const std::string& kind);
void write_json(const nlohmann::json& document, const std::string& path);

}  // namespace fluoro
