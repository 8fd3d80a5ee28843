// libFuzzer target: a MetaImage file (.mha) through read_volume (the header checks, then ITK's MetaIO) and
// read_image (a 2D image by the same name, through the same checks).
#include "fuzz/fuzz_input.hpp"
#include "engine/image_io.hpp"
#include "engine/volume_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".mha", [](const std::string& path) { fluoro::read_volume(path); },
                                    [](const std::string& path) { fluoro::read_image(path); });
}
