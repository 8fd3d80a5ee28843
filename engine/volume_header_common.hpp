#pragma once
// What the volume header checks (nifti_header, metaimage_header, nrrd_header) share.
#include <string>

namespace fluoro {

// Voxel bytes a header may describe: far beyond any CT (a 2048^3 double volume is 64 GiB), small
// enough that products of its counts and sizes cannot overflow.
inline constexpr double kMaxVolumeDataBytes = double(1ull << 42);
// Origins and offsets a header may hold, in its units (mm, but metres and microns exist).
inline constexpr double kMaxVolumeCoordinate = 1e12;

// s without its leading and trailing blanks (spaces, tabs, carriage returns).
inline std::string trim_blanks(const std::string& s) {
  const std::string::size_type b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return {};
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

}  // namespace fluoro
