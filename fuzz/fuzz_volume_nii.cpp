// libFuzzer target: a NIfTI-1/-2 volume (.nii) through read_volume (the header checks, then ITK).
#include "fuzz/fuzz_input.hpp"
#include "engine/volume_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".nii", [](const std::string& path) { fluoro::read_volume(path); });
}
