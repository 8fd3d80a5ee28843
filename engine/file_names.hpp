#pragma once
// Small helpers for choosing file formats by name, shared by the readers and writers.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <string>

namespace fluoro {

inline std::string to_lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

inline bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// The last extension in lower case, with its dot (".stl"), or "" when there is none.
inline std::string lower_extension(const std::string& path) {
  return to_lower(std::filesystem::path(path).extension().string());
}

// The file name (no directories) in lower case, for case-insensitive extension tests.
inline std::string lower_file_name(const std::string& path) {
  return to_lower(std::filesystem::path(path).filename().string());
}

}  // namespace fluoro
