#pragma once
// What every fuzz target shares. The readers take a path and pick the format by its name, so the
// fuzzer's bytes are written to a file with the right extension first. An InputError is the
// expected answer to bad bytes; anything else (another exception, a crash, a sanitizer report, a
// message that is not one line naming the file) is a finding: libFuzzer stops and keeps the input.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "engine/error.hpp"

namespace fluoro::fuzz {

// One file per process, in /dev/shm when it exists (a fuzzer writes it hundreds of times a second).
inline std::string input_path(const char* extension) {
  static const std::string dir = std::filesystem::is_directory("/dev/shm")
                                     ? std::string("/dev/shm")
                                     : std::filesystem::temp_directory_path().string();
  return dir + "/fluoro_fuzz_" + std::to_string(::getpid()) + extension;
}

// Runs read(path), and any InputError must keep the error contract: one line that names the file.
template <class Read>
void expect_contract(const std::string& path, Read&& read) {
  try {
    read(path);
  } catch (const InputError& e) {
    const std::string message = e.what();
    if (message.find('\n') != std::string::npos || message.find(path) == std::string::npos) {
      std::fprintf(stderr, "InputError breaks the one-line contract: %s\n", message.c_str());
      std::abort();
    }
  }
}

// Runs each reader on the bytes in turn (a file a volume reader and the image reader both take by
// its name goes to both); returns 0 as LLVMFuzzerTestOneInput must.
template <class... Read>
int read_as_file(const uint8_t* data, size_t size, const char* extension, Read&&... read) {
  const std::string path = input_path(extension);
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  }
  (expect_contract(path, read), ...);
  std::remove(path.c_str());
  return 0;
}

}  // namespace fluoro::fuzz
