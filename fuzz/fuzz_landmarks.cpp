// libFuzzer target: the landmark file of fluoro register --landmarks (two views).
#include "fuzz/fuzz_input.hpp"
#include "pipelines/registration/landmarks.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".json", [](const std::string& path) { fluoro::read_landmarks(path, 2); });
}
