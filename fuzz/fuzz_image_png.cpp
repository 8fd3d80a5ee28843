// libFuzzer target: a PNG X-ray through read_image (libpng, engine/png_reader.cpp).
#include "fuzz/fuzz_input.hpp"
#include "engine/image_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".png", [](const std::string& path) { fluoro::read_image(path); });
}
