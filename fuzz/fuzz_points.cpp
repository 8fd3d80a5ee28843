// libFuzzer target: 2D and 3D point lists (FORMATS.md).
#include "fuzz/fuzz_input.hpp"
#include "engine/point_list_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".json", [](const std::string& path) {
    try {
      fluoro::read_points_2d(path);
    } catch (const fluoro::InputError&) {
    }
    fluoro::read_points_3d(path);
  });
}
