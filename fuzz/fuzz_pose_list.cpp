// libFuzzer target: a pose list (pivot calibration's POSES.json).
#include "fuzz/fuzz_input.hpp"
#include "engine/pose_list_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".json", [](const std::string& path) { fluoro::read_pose_list(path); });
}
