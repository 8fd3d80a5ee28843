#include "apps/fluoro/result_files.hpp"

#include <filesystem>

#include "engine/error.hpp"

namespace fluoro::cli {

nlohmann::json file_digest(const std::string& path) {
  std::error_code ec;
  const auto size = std::filesystem::is_regular_file(path, ec) ? std::filesystem::file_size(path, ec) : 0;
  return {{"path", path}, {"bytes", ec ? 0 : size}};
}

void check_output_path(const std::string& path) {
  const std::filesystem::path target(path), dir = target.parent_path();
  std::error_code ec;
  if (target.filename().empty() || std::filesystem::is_directory(target, ec))
    throw_input_error(path, "output path is a directory");
  if (!dir.empty() && !std::filesystem::is_directory(dir, ec)) throw_input_error(path, "output directory does not exist");
}

void make_output_directory(const std::string& dir, const std::string& option) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir)) throw_input_error(option + " " + dir, "cannot create the directory");
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
