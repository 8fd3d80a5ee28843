// libFuzzer target: a NRRD file (.nrrd) through read_volume (ITK's NRRD reader) and read_image (a 2D image by
// the same name, through the same checks).
#include "fuzz/fuzz_input.hpp"
#include "engine/image_io.hpp"
#include "engine/volume_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".nrrd", [](const std::string& path) { fluoro::read_volume(path); },
                                    [](const std::string& path) { fluoro::read_image(path); });
}
