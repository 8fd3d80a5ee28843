// libFuzzer target: the sweep configuration SWEEP.json.
#include "fuzz/fuzz_input.hpp"
#include "pipelines/sweep/sweep.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return fluoro::fuzz::read_as_file(data, size, ".json", [](const std::string& path) { fluoro::read_sweep_config(path); });
}
