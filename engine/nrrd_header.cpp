#include "engine/nrrd_header.hpp"

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "engine/error.hpp"
#include "engine/file_names.hpp"
#include "engine/volume_header_common.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

constexpr double kDeflateMaxRatio = 1032.0;
constexpr size_t kMaxHeaderBytes = size_t(1) << 20;

[[noreturn]] void bad_nrrd(const std::string& path, const std::string& problem) {
  throw_input_error(path, "NRRD header: " + problem);
}

// Bytes of one value of a NRRD type name (teem's spellings); 0 for "block" and unknown names.
int type_bytes(const std::string& type) {
  static const std::map<std::string, int> sizes = {
      {"signed char", 1},         {"int8", 1},
      {"int8_t", 1},              {"uchar", 1},
      {"unsigned char", 1},       {"uint8", 1},
      {"uint8_t", 1},             {"short", 2},
      {"short int", 2},           {"signed short", 2},
      {"signed short int", 2},    {"int16", 2},
      {"int16_t", 2},             {"ushort", 2},
      {"unsigned short", 2},      {"unsigned short int", 2},
      {"uint16", 2},              {"uint16_t", 2},
      {"int", 4},                 {"signed int", 4},
      {"int32", 4},               {"int32_t", 4},
      {"uint", 4},                {"unsigned int", 4},
      {"uint32", 4},              {"uint32_t", 4},
      {"longlong", 8},            {"long long", 8},
      {"long long int", 8},       {"signed long long", 8},
      {"signed long long int", 8}, {"int64", 8},
      {"int64_t", 8},             {"ulonglong", 8},
      {"unsigned long long", 8},  {"unsigned long long int", 8},
      {"uint64", 8},              {"uint64_t", 8},
      {"float", 4},               {"double", 8}};
  const auto it = sizes.find(type);
  return it == sizes.end() ? 0 : it->second;
}

// A whole number from lo to hi, or refused naming the field.
int64_t integer(const std::string& path, const std::string& field, const std::string& value, int64_t lo, int64_t hi) {
  std::istringstream in(value);
  double v = 0;
  std::string rest;
  if (!(in >> v) || (in >> rest) || v != std::floor(v) || v < double(lo) || v > double(hi))
    bad_nrrd(path, field + " must be an integer from " + std::to_string(lo) + " to " + std::to_string(hi) + ", is \"" +
                  value + "\"");
  return int64_t(v);
}

}  // namespace

void check_nrrd_header(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_input_error(path, "cannot open file");
  std::string text(kMaxHeaderBytes, '\0');
  in.read(text.data(), std::streamsize(text.size()));
  text.resize(size_t(in.gcount()));
  if (text.size() < 9 || text.compare(0, 7, "NRRD000") != 0 || text[7] < '1' || text[7] > '5' ||
      (text[8] != '\n' && text[8] != '\r'))
    bad_nrrd(path, "no NRRD0001..NRRD0005 magic line (not a NRRD file)");

  // Fields "name: value" up to the first empty line (the attached data follow it) or the end of
  // a detached header; "key:=value" pairs and "#" comments say nothing about the data.
  std::map<std::string, std::string> fields;
  size_t p = text.find('\n') + 1;
  size_t data_start = std::string::npos;
  while (p < text.size()) {
    const size_t end = std::min(text.find('\n', p), text.size());
    const std::string line = text.substr(p, end - p);
    p = end + 1;
    if (trim_blanks(line).empty()) {
      data_start = std::min(p, text.size());
      break;
    }
    if (line[0] == '#' || line.find(":=") != std::string::npos) continue;
    const size_t colon = line.find(": ");
    if (colon == std::string::npos) bad_nrrd(path, "a header line without \"field: value\" (corrupt header?)");
    const std::string name = to_lower(trim_blanks(line.substr(0, colon)));
    if (fields.count(name)) bad_nrrd(path, "field \"" + name + "\" given twice");
    fields[name] = trim_blanks(line.substr(colon + 2));
    // "data file: LIST": the rest of the header file names the data files, one a line.
    if ((name == "data file" || name == "datafile") && fields[name].rfind("LIST", 0) == 0) break;
  }
  if (data_start == std::string::npos && text.size() == kMaxHeaderBytes) bad_nrrd(path, "no end of header in 1 MiB");
  const auto field = [&](std::initializer_list<const char*> names) -> const std::string* {
    for (const char* n : names)
      if (fields.count(n)) return &fields.at(n);
    return nullptr;
  };
  for (const char* required : {"type", "dimension", "sizes", "encoding"})
    if (!fields.count(required)) bad_nrrd(path, std::string("no \"") + required + "\" field (file truncated or not a NRRD)");

  const std::string type = to_lower(fields["type"]);
  const int bytes = type_bytes(type);
  if (bytes == 0) bad_nrrd(path, "unsupported type \"" + fields["type"] + "\"");
  const int64_t dimension = integer(path, "dimension", fields["dimension"], 1, 16);
  std::istringstream size_text(fields["sizes"]);
  std::vector<std::string> sizes{std::istream_iterator<std::string>(size_text), std::istream_iterator<std::string>()};
  if (int64_t(sizes.size()) != dimension)
    bad_nrrd(path, "sizes must be " + std::to_string(dimension) + " numbers (the dimension), is \"" + fields["sizes"] + "\"");
  double values = 1;
  for (const std::string& s : sizes) values *= double(integer(path, "sizes", s, 1, 2147483647));
  const double voxel_bytes = values * bytes;
  if (voxel_bytes > kMaxVolumeDataBytes) bad_nrrd(path, "sizes describe more than 4 TiB of voxels");

  const std::string encoding = to_lower(fields["encoding"]);
  double need = 0;  // the fewest data bytes that can hold the voxels
  if (encoding == "raw")
    need = voxel_bytes;
  else if (encoding == "hex")
    need = 2 * voxel_bytes;
  else if (encoding == "txt" || encoding == "text" || encoding == "ascii")
    need = values;
  else if (encoding == "gz" || encoding == "gzip")
    need = std::ceil(voxel_bytes / kDeflateMaxRatio);
  else if (encoding == "bz2" || encoding == "bzip2")
    bad_nrrd(path, "bzip2 encoding (ITK's NRRD reader is built without it; use raw or gzip)");
  else
    bad_nrrd(path, "unknown encoding \"" + fields["encoding"] + "\"");

  int64_t byte_skip = 0;
  if (const std::string* v = field({"byte skip", "byteskip"})) byte_skip = integer(path, "byte skip", *v, -1, int64_t(kMaxVolumeDataBytes));
  if (byte_skip == -1 && encoding != "raw") bad_nrrd(path, "byte skip -1 (data at the file's end) needs raw encoding");
  if (const std::string* v = field({"line skip", "lineskip"})) integer(path, "line skip", *v, 0, 1 << 30);

  std::error_code ec;
  uint64_t have = 0;
  if (const std::string* data_file = field({"data file", "datafile"})) {
    // "LIST" and "pattern min max step" spread the data over files that teem checks itself.
    if (data_file->rfind("LIST", 0) == 0 || data_file->find_first_of(" \t") != std::string::npos) return;
    if (data_file->empty()) bad_nrrd(path, "empty data file");
    fs::path data = *data_file;
    if (data.is_relative()) data = fs::path(path).parent_path() / data;
    if (!fs::is_regular_file(data, ec)) throw_input_error(path, "data file " + data.string() + " not found");
    have = fs::file_size(data, ec);
  } else {
    const uint64_t size = fs::file_size(path, ec);
    have = data_start == std::string::npos || size < data_start ? 0 : size - data_start;
  }
  if (byte_skip > 0) need += double(byte_skip);
  if (double(have) < need)
    throw_input_error(path, "file truncated (" + std::to_string(have) + " data bytes; the header's sizes, type and " +
                                encoding + " encoding need at least " + std::to_string(uint64_t(need)) + ")");
}

}  // namespace fluoro
