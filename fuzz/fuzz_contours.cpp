// libFuzzer target: the traced contours of fluoro register --contours (two views of 64 x 48 and 48 x 64).
#include "fuzz/fuzz_input.hpp"
#include "pipelines/registration/registration_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".json", [](const std::string& path) { fluoro::read_contours(path, {64, 48}, {48, 64}); });
}
