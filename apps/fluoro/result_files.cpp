#include "apps/fluoro/result_files.hpp"

#include <filesystem>

namespace fluoro::cli {

nlohmann::json file_digest(const std::string& path) {
  std::error_code ec;
  const auto size = std::filesystem::is_regular_file(path, ec) ? std::filesystem::file_size(path, ec) : 0;
  return {{"path", path}, {"bytes", ec ? 0 : size}};
}

double StageTimer::lap(const std::string& stage) {
  const auto now = std::chrono::steady_clock::now();
  const double s = std::chrono::duration<double>(now - last_).count();
  last_ = now;
  stages_[stage] = stages_.value(stage, 0.0) + s;
  return s;
}

double StageTimer::total() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

}  // namespace fluoro::cli
