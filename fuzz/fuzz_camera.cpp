// libFuzzer target: a camera file (K, R, t or P; docs/conventions.md).
#include "fuzz/fuzz_input.hpp"
#include "engine/json_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".json", [](const std::string& path) { fluoro::read_camera(path); });
}
