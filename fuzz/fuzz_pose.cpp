// libFuzzer target: a pose file (T_world_ct).
#include "fuzz/fuzz_input.hpp"
#include "engine/json_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".json", [](const std::string& path) { fluoro::read_pose(path); });
}
