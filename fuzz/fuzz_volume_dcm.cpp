// libFuzzer target: a DICOM volume (.dcm) through read_volume (the DICOM check, then GDCM).
#include "fuzz/fuzz_input.hpp"
#include "engine/volume_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".dcm", [](const std::string& path) { fluoro::read_volume(path); });
}
