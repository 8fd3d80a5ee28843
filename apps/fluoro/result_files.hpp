#pragma once
// Pieces every result document shares (shared/docs/FORMATS.md): the inputs' digest, per-stage
// timings, and the failure that writes its result file and exits with code 3.
#include <chrono>
#include <nlohmann/json.hpp>
#include <string>

namespace fluoro::cli {

// {"path": path, "bytes": size} of an input file (0 bytes when it is not a regular file).
nlohmann::json file_digest(const std::string& path);

// Throws InputError naming `path` when it cannot be an output file (a directory, or in a directory
// that does not exist). Called for every output before anything is written, so that a command with
// two outputs never leaves the first behind when the second is bad.
void check_output_path(const std::string& path);

// Creates an output directory (and its parents); throws InputError naming it when it cannot.
void make_output_directory(const std::string& dir, const std::string& option = "--out-dir");

// Seconds of wall clock since `t`.
inline double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// Wall-clock stage timer: `lap("detect")` records the seconds since the previous lap (or the
// start) under that name; `json()` is the "timings_s" object of a result file.
class StageTimer {
 public:
  StageTimer() : last_(std::chrono::steady_clock::now()), start_(last_) {}
  double lap(const std::string& stage);
  double total() const;
  const nlohmann::json& json() const { return stages_; }

 private:
  std::chrono::steady_clock::time_point last_, start_;
  nlohmann::json stages_ = nlohmann::json::object();
};

}  // namespace fluoro::cli
