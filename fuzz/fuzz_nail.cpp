// libFuzzer target: the nail model NAIL.json.
#include "fuzz/fuzz_input.hpp"
#include "engine/distal_locking_models.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".json", [](const std::string& path) { fluoro::read_nail_model(path); });
}
