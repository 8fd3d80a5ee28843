// libFuzzer target: a TIFF X-ray (8/16-bit, float) through read_image (ITK's TIFF reader, libtiff).
#include "fuzz/fuzz_input.hpp"
#include "engine/image_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".tif", [](const std::string& path) { fluoro::read_image(path); });
}
