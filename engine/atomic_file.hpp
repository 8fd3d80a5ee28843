#pragma once
// Atomic output: write to a temporary file beside the target, then rename over it, so a crash or
// a bad input never leaves a half-written file and an older output stays intact until replaced.
#include <functional>
#include <string>

namespace fluoro {

// Calls write(tmp_path); on success renames tmp_path to path, on any exception removes tmp_path
// and rethrows. The temporary keeps path's extension (writers choose formats by it).
void write_file_atomic(const std::string& path, const std::function<void(const std::string&)>& write);

}  // namespace fluoro
