#include "engine/metaimage_header.hpp"

#include <Eigen/Core>
#include <Eigen/LU>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "engine/error.hpp"
#include "engine/file_names.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

constexpr double kMaxDataBytes = double(1ull << 42);  // as for NIfTI: far beyond any CT
constexpr double kMaxCoordinate = 1e12;
constexpr size_t kMaxKeyBytes = 200;  // MetaIO's field names hold 255

[[noreturn]] void bad(const std::string& path, const std::string& problem) {
  throw_input_error(path, "MetaImage header: " + problem);
}

std::string trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return {};
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

// The whitespace-separated numbers of a value; ok = false when a token is not a number.
std::vector<double> numbers(const std::string& value, bool& ok) {
  std::vector<double> out;
  std::istringstream in(value);
  std::string token;
  ok = true;
  while (in >> token) {
    char* end = nullptr;
    const double v = std::strtod(token.c_str(), &end);
    if (end == token.c_str() || *end != '\0') ok = false;
    out.push_back(v);
  }
  return out;
}

std::vector<double> require_numbers(const std::map<std::string, std::string>& keys, const std::string& key,
                                    size_t count, const std::string& path) {
  bool ok = false;
  const std::vector<double> v = numbers(keys.at(key), ok);
  if (!ok || v.size() != count)
    bad(path, key + " must be " + std::to_string(count) + " numbers, is \"" + keys.at(key) + "\"");
  for (double x : v)
    if (!std::isfinite(x)) bad(path, key + " has a non-finite value");
  return v;
}

int64_t require_integer(const std::string& key, const std::string& value, int64_t lo, int64_t hi,
                        const std::string& path) {
  bool ok = false;
  const std::vector<double> v = numbers(value, ok);
  if (!ok || v.size() != 1 || v[0] != std::floor(v[0]) || v[0] < double(lo) || v[0] > double(hi))
    bad(path, key + " must be an integer from " + std::to_string(lo) + " to " + std::to_string(hi) + ", is \"" +
                  value + "\"");
  return int64_t(v[0]);
}

// Bytes of one component of the element types ITK reads as scalars (their _ARRAY forms carry
// ElementNumberOfChannels components); 0 otherwise.
int element_bytes(std::string type) {
  if (ends_with(type, "_ARRAY")) type.resize(type.size() - 6);
  static const std::map<std::string, int> sizes = {
      {"MET_CHAR", 1},  {"MET_UCHAR", 1},     {"MET_SHORT", 2},      {"MET_USHORT", 2},
      {"MET_INT", 4},   {"MET_UINT", 4},      {"MET_LONG", 4},       {"MET_ULONG", 4},
      {"MET_FLOAT", 4}, {"MET_DOUBLE", 8},    {"MET_LONG_LONG", 8},  {"MET_ULONG_LONG", 8}};
  const auto it = sizes.find(type);
  return it == sizes.end() ? 0 : it->second;
}

}  // namespace

void check_metaimage_header(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_input_error(path, "cannot open file");
  std::map<std::string, std::string> keys;
  std::string line;
  uint64_t header_bytes = 0;
  // The header is text up to ElementDataFile, the last key; 1 MiB without one is not a header.
  // MetaIO copies each key (everything up to the next '=', across lines without one) into a
  // 255-byte field name with strcpy: a longer one overflows it (glibc aborts; fuzz_volume_mha).
  size_t key_bytes = 0;
  while (header_bytes < (1u << 20) && std::getline(in, line)) {
    header_bytes += line.size() + (in.eof() ? 0 : 1);
    const size_t eq = line.find('=');
    if (eq == std::string::npos) {
      key_bytes += line.size() + 1;
      if (key_bytes > kMaxKeyBytes) bad(path, "a header line too long for a key (corrupt header?)");
      continue;
    }
    if (key_bytes + eq > kMaxKeyBytes) bad(path, "a key longer than " + std::to_string(kMaxKeyBytes) + " characters");
    key_bytes = 0;
    const std::string key = trim(line.substr(0, eq));
    keys[key] = trim(line.substr(eq + 1));
    if (key == "ElementDataFile") break;
  }
  for (const char* required : {"NDims", "DimSize", "ElementType", "ElementDataFile"})
    if (!keys.count(required)) bad(path, std::string("no ") + required + " (file truncated or not a MetaImage)");

  const size_t ndims = size_t(require_integer("NDims", keys["NDims"], 1, 10, path));
  double voxels = 1;
  for (double d : require_numbers(keys, "DimSize", ndims, path)) {
    if (d < 1 || d != std::floor(d) || d > 2147483647.0) bad(path, "DimSize must be positive integers, is \"" + keys["DimSize"] + "\"");
    voxels *= d;
  }
  const int bytes = element_bytes(keys["ElementType"]);
  if (bytes == 0) bad(path, "unsupported ElementType " + keys["ElementType"]);
  int64_t channels = 1;
  if (keys.count("ElementNumberOfChannels"))
    channels = require_integer("ElementNumberOfChannels", keys["ElementNumberOfChannels"], 1, 1024, path);
  const double raw_bytes = voxels * double(bytes) * double(channels);
  if (raw_bytes > kMaxDataBytes) bad(path, "DimSize describes more than 4 TiB of voxels");

  for (const char* key : {"ElementSpacing", "ElementSize"})
    if (keys.count(key))
      for (double s : require_numbers(keys, key, ndims, path))
        if (!(s > 0)) bad(path, std::string("voxel spacing ") + key + " must be positive, is \"" + keys[key] + "\"");
  for (const char* key : {"Offset", "Origin", "Position", "CenterOfRotation"})
    if (keys.count(key))
      for (double o : require_numbers(keys, key, ndims, path))
        if (!(std::abs(o) <= kMaxCoordinate)) bad(path, std::string(key) + " is out of range");
  for (const char* key : {"TransformMatrix", "Rotation", "Orientation"}) {
    if (!keys.count(key)) continue;
    const std::vector<double> m = require_numbers(keys, key, ndims * ndims, path);
    if (ndims == 3) {
      // Columns normalised: the axes must span space (ITK inverts the direction matrix).
      Eigen::Matrix3d d = Eigen::Map<const Eigen::Matrix3d>(m.data());
      for (int c = 0; c < 3; ++c) {
        const double n = d.col(c).norm();
        if (!(n > 0)) bad(path, std::string(key) + " has a zero axis");
        d.col(c) /= n;
      }
      if (!(std::abs(d.determinant()) > 1e-6)) bad(path, std::string(key) + " axes are (nearly) parallel");
    }
  }
  int64_t header_size = 0;
  if (keys.count("HeaderSize"))
    header_size = require_integer("HeaderSize", keys["HeaderSize"], -1, int64_t(kMaxDataBytes), path);
  bool compressed = false;
  if (keys.count("CompressedData")) {
    const std::string v = to_lower(keys["CompressedData"]);
    if (v != "true" && v != "false") bad(path, "CompressedData must be True or False");
    compressed = v == "true";
  }
  const std::string& data_file = keys["ElementDataFile"];
  if (data_file.empty()) bad(path, "ElementDataFile is empty");
  for (const char c : data_file)
    if (static_cast<unsigned char>(c) < 0x20) bad(path, "ElementDataFile holds control characters");
  // "LIST" and printf-style patterns spread the data over several files: MetaIO checks those,
  // but divides by the pattern's step without looking (SIGFPE on a step of 0; fuzz_volume_mha).
  if (data_file.rfind("LIST", 0) != 0 && data_file.find_first_of(" \t") != std::string::npos) {
    bool ok = false;
    const std::vector<double> range = numbers(data_file.substr(data_file.find_first_of(" \t")), ok);
    if (!ok || range.size() < 3 || range[2] == 0 || (range[1] - range[0]) / range[2] < 0 ||
        (range[1] - range[0]) / range[2] > 1e6)
      bad(path, "ElementDataFile is neither a file name nor a \"pattern first last step\" list");
  }
  if (keys.count("BinaryData") && to_lower(keys["BinaryData"]) == "false") return;  // ASCII voxels: not sized
  double need = raw_bytes;
  if (compressed) {
    // ITK and MetaIO always write it; without it MetaIO sizes its buffer from where it thinks the
    // header ended, and a corrupt header made that 2^64 bytes (fuzz_volume_mha).
    if (!keys.count("CompressedDataSize")) bad(path, "compressed data without CompressedDataSize");
    need = double(require_integer("CompressedDataSize", keys["CompressedDataSize"], 1, int64_t(kMaxDataBytes), path));
  }
  if (header_size < 0) return;  // HeaderSize -1: the data are the file's last bytes

  std::error_code ec;
  uint64_t have = 0;
  if (to_lower(data_file) == "local") {
    const uint64_t size = fs::file_size(path, ec);
    have = size > header_bytes ? size - header_bytes : 0;
  } else {
    if (data_file.rfind("LIST", 0) == 0 || data_file.find_first_of(" \t") != std::string::npos) return;
    fs::path data = data_file;
    if (data.is_relative()) data = fs::path(path).parent_path() / data;
    if (!fs::is_regular_file(data, ec)) throw_input_error(path, "data file " + data.string() + " not found");
    have = fs::file_size(data, ec);
    need += double(header_size);  // HeaderSize bytes skipped at the start of the data file
  }
  if (double(have) < need)
    throw_input_error(path, "file truncated (" + std::to_string(have) + " of the " + std::to_string(uint64_t(need)) +
                                " bytes its header describes are present)");
}

}  // namespace fluoro
