// libFuzzer target: a NIfTI-1/-2 file (.nii) through read_volume (the header checks, then ITK) and read_image
// (a 2D image by the same name).
#include "fuzz/fuzz_input.hpp"
#include "engine/image_io.hpp"
#include "engine/volume_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".nii", [](const std::string& path) { fluoro::read_volume(path); },
                                    [](const std::string& path) { fluoro::read_image(path); });
}
