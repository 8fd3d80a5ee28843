// libFuzzer target: the STL mesh parser, which reads from a buffer (engine/mesh_format_readers.hpp).
#include <cstdint>
#include <string>

#include "engine/error.hpp"
#include "engine/mesh_format_readers.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    fluoro::mesh_detail::read_stl(std::string(reinterpret_cast<const char*>(data), size), "mesh.stl");
  } catch (const fluoro::InputError&) {
    // the expected answer to bad bytes
  }
  return 0;
}
