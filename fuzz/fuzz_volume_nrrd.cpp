// libFuzzer target: a NRRD volume (.nrrd) through read_volume (ITK's NRRD reader).
#include "fuzz/fuzz_input.hpp"
#include "engine/volume_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".nrrd", [](const std::string& path) { fluoro::read_volume(path); });
}
