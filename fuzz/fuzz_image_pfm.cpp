// libFuzzer target: a PFM float image through read_image (the project's own parser).
#include "fuzz/fuzz_input.hpp"
#include "engine/image_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".pfm", [](const std::string& path) { fluoro::read_image(path); });
}
