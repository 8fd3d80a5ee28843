#pragma once
// A list of rigid transforms in a JSON file, e.g. a tracked tool's poses for pivot calibration:
// {"poses": [[[4x4 row-major]], ...]} (shared/docs/FORMATS.md, "Point tools").
#include <string>
#include <vector>

#include "engine/pose.hpp"

namespace fluoro {

// Every entry of the array under `key` as a Pose. Throws InputError naming the path (and the pose)
// for a missing file, bad JSON, a missing array, a matrix that is not 4x4 numbers, NaN, or a
// transform that is not rigid.
std::vector<Pose> read_pose_list(const std::string& path, const std::string& key = "poses");

}  // namespace fluoro
