// libFuzzer target: the calibration phantom model PHANTOM.json.
#include "fuzz/fuzz_input.hpp"
#include "engine/phantom_model.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".json", [](const std::string& path) { fluoro::read_phantom_model(path); });
}
