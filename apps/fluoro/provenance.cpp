#include "apps/fluoro/provenance.hpp"

#include <cstdio>
#include <filesystem>
#include <vector>

#include "apps/fluoro/global_options.hpp"
#include "apps/fluoro/result_files.hpp"
#include "engine/sha256.hpp"
#include "engine/thread_limit.hpp"
#include "engine/version.hpp"
#include "kernels/cpu/simd_targets.hpp"

namespace fluoro::cli {
namespace {

namespace fs = std::filesystem;

// Every {"path": ...} object in `j`, depth first, in document order.
void collect_paths(const nlohmann::json& j, std::vector<std::string>& paths) {
  if (j.is_object() && j.contains("path") && j["path"].is_string()) {
    paths.push_back(j["path"].get<std::string>());
    return;
  }
  if (j.is_structured())
    for (const auto& item : j) collect_paths(item, paths);
}

}  // namespace

nlohmann::json input_sha256(const std::string& path) {
  std::error_code ec;
  if (fs::is_regular_file(path, ec) || fs::is_directory(path, ec)) return sha256_of_input(path);
  return nullptr;
}

nlohmann::json provenance(const std::string& command, const nlohmann::json& settings, const nlohmann::json& inputs) {
  StageTimer timer;
  std::vector<std::string> paths;
  collect_paths(inputs, paths);
  nlohmann::json files = nlohmann::json::array();
  for (const auto& path : paths) {
    nlohmann::json entry = file_digest(path);
    entry["sha256"] = input_sha256(path);
    if (verbose() && entry["sha256"].is_string())
      std::fprintf(stderr, "fluoro: sha256 %s  %s\n", entry["sha256"].get<std::string>().c_str(), path.c_str());
    files.push_back(entry);
  }
  return {{"program", "fluoro"},
          {"version", kVersion},
          {"command", command},
          {"arguments", arguments()},
          {"settings", settings},
          {"threads", thread_limit()},
          {"cpu_simd", cpu::simd_target()},
          {"inputs", files},
          {"sha256_seconds", timer.total()}};
}

}  // namespace fluoro::cli
