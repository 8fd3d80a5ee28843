#include "engine/metaimage_header.hpp"

#include <zlib.h>

#include <Eigen/Core>
#include <Eigen/LU>
#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <new>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "engine/error.hpp"
#include "engine/file_names.hpp"
#include "engine/volume_header_common.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

constexpr size_t kMaxKeyBytes = 200;  // MetaIO's field names hold 255

[[noreturn]] void bad_metaimage(const std::string& path, const std::string& problem) {
  throw_input_error(path, "MetaImage header: " + problem);
}

// A byte or file count (a whole, non-negative double) as text.
std::string number_text(double v) { return std::to_string(uint64_t(v)); }

// The whitespace-separated numbers of a value; ok = false when a token is not a number.
std::vector<double> numbers(const std::string& value, bool& ok) {
  std::vector<double> out;
  std::istringstream in(value);
  std::string token;
  ok = true;
  while (in >> token) {
    // Plain decimal numbers only, as MetaIO's >> reads them (strtod would also take "nan",
    // "inf" and hexadecimal, where >> stops and MetaIO's reading derails).
    if (token.find_first_not_of("0123456789+-.eE") != std::string::npos) ok = false;
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
    bad_metaimage(path, key + " must be " + std::to_string(count) + " numbers, is \"" + keys.at(key) + "\"");
  for (double x : v)
    if (!std::isfinite(x)) bad_metaimage(path, key + " has a non-finite value");
  return v;
}

int64_t require_integer(const std::string& key, const std::string& value, int64_t lo, int64_t hi,
                        const std::string& path) {
  bool ok = false;
  const std::vector<double> v = numbers(value, ok);
  if (!ok || v.size() != 1 || v[0] != std::floor(v[0]) || v[0] < double(lo) || v[0] > double(hi))
    bad_metaimage(path, key + " must be an integer from " + std::to_string(lo) + " to " + std::to_string(hi) + ", is \"" +
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



// The fields of a header split as MetaIO's MET_Read splits them, so that what is checked here is
// what MetaIO will read. MET_Read takes a key up to '=', ':' or the end of the line, then skips to
// the next '=' or ':' (across lines: a line without one takes the next line's value) and past any
// run of '=', ':' and blanks; a number field is read with >> (across lines too), a text field to the
// end of the line. Its arrays take their length from NDims as read so far, cast to size_t: a
// negative NDims before DimSize made it read 2^64 numbers (the hang of fuzz_volume_mha's
// "metaio_read_never_ends"), and a large one overflows the field's 4096 values. Here a key is
// refused unless it is on its own line with its value, given once, and a number field holds
// exactly the numbers MetaIO will read, after a valid NDims when its length depends on it.
struct HeaderFields {
  std::map<std::string, std::string> keys;
  uint64_t header_bytes = 0;  // where the data of an ElementDataFile = LOCAL begin
  // The ElementDataFile line ends in the text read (MetaIO's getline takes its '\n' too; a header
  // longer than the text read would put the data's start out of sight).
  bool data_line_ended = false;
};

// How many numbers MetaIO reads for a number field: a fixed count, NDims or NDims^2 (text: none;
// the fields of MetaObject and MetaImage in ITK 5.2).
enum class Count { text, one, four, ndims, ndims_squared };
Count number_count(const std::string& key) {
  static const std::map<std::string, Count> counts = {
      {"NDims", Count::one},
      {"ID", Count::one},
      {"ParentID", Count::one},
      {"CompressedDataSize", Count::one},
      {"HeaderSize", Count::one},
      {"ElementMin", Count::one},
      {"ElementMax", Count::one},
      {"ElementNumberOfChannels", Count::one},
      {"ElementNBits", Count::one},
      {"ElementToIntensityFunctionSlope", Count::one},
      {"ElementToIntensityFunctionOffset", Count::one},
      {"Color", Count::four},
      {"SequenceID", Count::four},
      {"Position", Count::ndims},
      {"ImagePosition", Count::ndims},
      {"Origin", Count::ndims},
      {"Offset", Count::ndims},
      {"CenterOfRotation", Count::ndims},
      {"ElementSpacing", Count::ndims},
      {"ElementSize", Count::ndims},
      {"DimSize", Count::ndims},
      {"TransformMatrix", Count::ndims_squared},
      {"Rotation", Count::ndims_squared},
      {"Orientation", Count::ndims_squared},
  };
  const auto it = counts.find(key);
  return it == counts.end() ? Count::text : it->second;
}

HeaderFields split_header(const std::string& text, const std::string& path) {
  HeaderFields out;
  const size_t n = text.size();
  size_t p = 0;
  size_t line = 1;
  int64_t ndims = 0;
  auto count_lines = [&](size_t from, size_t to) {
    for (size_t i = from; i < to && i < n; ++i) line += text[i] == '\n';
  };
  while (true) {
    const size_t skipped = p;
    while (p < n && std::isspace(static_cast<unsigned char>(text[p]))) ++p;
    count_lines(skipped, p);
    if (p >= n) break;
    const size_t start = p;
    while (p < n && text[p] != '=' && text[p] != ':' && text[p] != '\r' && text[p] != '\n') {
      // MetaIO copies a key with strcpy into a 255-byte field name: a longer one overflowed it
      // (glibc's abort, fuzz_volume_mha).
      if (p - start >= kMaxKeyBytes) bad_metaimage(path, "line " + std::to_string(line) + ": a key longer than " +
                                                   std::to_string(kMaxKeyBytes) + " characters");
      ++p;
    }
    if (p >= n) break;  // text without '=' at the end: MetaIO stops there too
    const std::string key = trim_blanks(text.substr(start, p - start));
    const std::string where = "line " + std::to_string(line) + ": ";
    if (text[p] != '=' && text[p] != ':')
      bad_metaimage(path, where + "no '=' after \"" + key + "\" (MetaIO would take the next line's value for it)");
    if (key.empty()) bad_metaimage(path, where + "a value without a key");
    // MetaIO compares keys as C strings: "NDims" followed by a NUL and anything would be NDims.
    for (const char c : key)
      if (static_cast<unsigned char>(c) < 0x20 && c != '\t') bad_metaimage(path, where + "a key with control characters");
    while (p < n && (text[p] == '=' || text[p] == ':' || text[p] == ' ' || text[p] == '\t')) ++p;
    // MetaIO keeps a '\r' that starts a value (it trims only the end), and reads a flag by its first
    // character: "BinaryData = \rTrue" is false to it, true to a trimmed reading.
    if (p + 1 < n && text[p] == '\r' && text[p + 1] != '\n')
      bad_metaimage(path, where + key + "'s value starts with a carriage return");
    const size_t end = std::min(text.find('\n', p), n);
    const std::string value = trim_blanks(text.substr(p, end - p));
    // MetaIO reads the rest of a line into a 500-byte buffer; a longer one stops its reading.
    if (end - p >= 500) bad_metaimage(path, where + key + "'s value is longer than 499 characters");
    if (out.keys.count(key)) bad_metaimage(path, where + key + " is given twice");
    out.keys[key] = value;

    const Count count = number_count(key);
    if (count != Count::text) {
      size_t expected = 1;
      if (count == Count::four) expected = 4;
      if (count == Count::ndims || count == Count::ndims_squared) {
        if (ndims == 0) bad_metaimage(path, where + key + " before NDims");
        expected = count == Count::ndims ? size_t(ndims) : size_t(ndims * ndims);
      }
      bool ok = false;
      const std::vector<double> v = numbers(value, ok);
      // A line with fewer numbers sends MetaIO's >> to the next line's key.
      if (!ok || v.size() != expected)
        bad_metaimage(path, where + key + " must be " + std::to_string(expected) + (expected == 1 ? " number" : " numbers") +
                      ", is \"" + value + "\"");
      if (key == "NDims") ndims = require_integer("NDims", value, 1, 10, path);
    }
    p = end < n ? end + 1 : n;
    count_lines(start, p);
    if (key == "ElementDataFile") {  // MetaIO stops here: the data (of LOCAL) follow
      out.header_bytes = p;
      out.data_line_ended = end < n;
      break;
    }
  }
  return out;
}

// The stored type of the element types read_metaimage_voxels reads (MET_LONG and MET_ULONG are 4
// bytes to MetaIO but a long is 8 here: left to ITK). ITK converts MET_CHAR through plain char.
std::optional<StoredType> stored_type(const std::string& element_type) {
  static const std::map<std::string, StoredType> types = {
      {"MET_UCHAR", StoredType::u8},
      {"MET_CHAR", std::is_signed_v<char> ? StoredType::i8 : StoredType::u8},
      {"MET_SHORT", StoredType::i16},
      {"MET_USHORT", StoredType::u16},
      {"MET_INT", StoredType::i32},
      {"MET_UINT", StoredType::u32},
      {"MET_LONG_LONG", StoredType::i64},
      {"MET_ULONG_LONG", StoredType::u64},
      {"MET_FLOAT", StoredType::f32},
      {"MET_DOUBLE", StoredType::f64}};
  const auto it = types.find(element_type);
  if (it == types.end()) return std::nullopt;
  return it->second;
}

// A byte-order key that leaves the data in this (little-endian) machine's order: absent or False.
bool native_order(const std::map<std::string, std::string>& keys) {
  if constexpr (std::endian::native != std::endian::little) return false;
  for (const char* key : {"BinaryDataByteOrderMSB", "ElementByteOrderMSB"})
    if (keys.count(key) && to_lower(keys.at(key)) != "false") return false;
  return true;
}

// ElementDataFile = "LIST [file_dim]": the names of the slice files follow the header, one a line,
// each holding file_dim-dimensional slices (default NDims - 1). MetaIO reads each line's last
// character without looking at its length (an empty line: s[-1], a SEGV found by fuzz_volume_mha),
// takes a negative file_dim for a count of dimensions (reading DimSize[-1]), stops silently at the
// end of the file (the slices not named left as garbage), and reads each named file as far as it
// goes. So: a whole number of complete, non-empty lines, one per slice file, each an existing file
// that holds its slice.
struct SliceList {
  std::vector<int64_t> dims;
  int element_bytes = 0;
  int64_t channels = 1;
  bool binary = true, compressed = false;
  int64_t header_size = 0;
};

void check_slice_list(const std::string& path, const std::string& text, const HeaderFields& fields,
                      const std::string& data_file, const SliceList& list) {
  const int ndims = int(list.dims.size());
  std::istringstream words(data_file);
  std::string word;
  words >> word;  // LIST...
  int file_dim = ndims - 1;
  if (words >> word) {
    // MetaIO's documented form is "LIST 2D" (it reads the number with atof); a bare number too.
    if (word.size() > 1 && (word.back() == 'D' || word.back() == 'd')) word.pop_back();
    const int64_t d = require_integer("ElementDataFile's LIST dimension", word, 0, ndims, path);
    if (d > 0) file_dim = int(d);
  }
  if (list.compressed) bad_metaimage(path, "compressed data in a LIST of slice files is not supported");
  if (!fields.data_line_ended) bad_metaimage(path, "no slice file names after ElementDataFile = LIST");
  double files = 1, slice_bytes = double(list.element_bytes) * double(list.channels);
  for (int i = 0; i < ndims; ++i) (i >= file_dim ? files : slice_bytes) *= double(list.dims[size_t(i)]);
  if (files > 1e5) bad_metaimage(path, "a LIST of " + number_text(files) + " slice files (at most 100,000)");
  const fs::path dir = fs::path(path).parent_path();
  const double need = slice_bytes + double(std::max<int64_t>(list.header_size, 0));
  const auto trailing = [](char c) {
    return std::isspace(static_cast<unsigned char>(c)) || !std::isprint(static_cast<unsigned char>(c));
  };
  size_t at = size_t(fields.header_bytes);
  for (int k = 0; k < int(files); ++k) {
    const size_t end = text.find('\n', at);
    if (end == std::string::npos)
      bad_metaimage(path, "the LIST names " + std::to_string(k) + " of the " + number_text(files) +
                    " slice files DimSize needs (each on a line of its own)");
    std::string name = text.substr(at, end - at);
    // MetaIO's trim: trailing blanks and unprintable characters, never the first character.
    size_t j = name.size();
    while (j > 1 && trailing(name[j - 1])) --j;
    name.resize(j);
    if (name.empty()) bad_metaimage(path, "an empty line in the LIST of slice files");
    fs::path file = name;
    if (file.is_relative()) file = dir / file;
    std::error_code ec;
    if (!fs::is_regular_file(file, ec)) throw_input_error(path, "slice file " + file.string() + " not found");
    const double size = double(fs::file_size(file, ec));
    if (list.binary && size < need)
      throw_input_error(path, "slice file " + file.string() + " truncated (" + number_text(size) + " of the " +
                                  number_text(need) + " bytes its slice needs)");
    at = end + 1;
  }
}

std::optional<MetaImageVoxels> check_metaimage_file(const std::string& path, bool want_voxels) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_input_error(path, "cannot open file");
  // The header is text up to ElementDataFile, the last key; 1 MiB without one is not a header.
  std::string text(size_t(1) << 20, '\0');
  in.read(text.data(), std::streamsize(text.size()));
  text.resize(size_t(in.gcount()));
  const HeaderFields fields = split_header(text, path);
  std::map<std::string, std::string> keys = fields.keys;
  const uint64_t header_bytes = fields.header_bytes;
  for (const char* required : {"NDims", "DimSize", "ElementType", "ElementDataFile"})
    if (!keys.count(required)) bad_metaimage(path, std::string("no ") + required + " (file truncated or not a MetaImage)");

  const size_t ndims = size_t(require_integer("NDims", keys["NDims"], 1, 10, path));
  double voxels = 1;
  std::vector<int64_t> dims;
  for (double d : require_numbers(keys, "DimSize", ndims, path)) {
    if (d < 1 || d != std::floor(d) || d > 2147483647.0) bad_metaimage(path, "DimSize must be positive integers, is \"" + keys["DimSize"] + "\"");
    voxels *= d;
    dims.push_back(int64_t(d));
  }
  const int bytes = element_bytes(keys["ElementType"]);
  if (bytes == 0) bad_metaimage(path, "unsupported ElementType " + keys["ElementType"]);
  int64_t channels = 1;
  if (keys.count("ElementNumberOfChannels"))
    channels = require_integer("ElementNumberOfChannels", keys["ElementNumberOfChannels"], 1, 1024, path);
  const double raw_bytes = voxels * double(bytes) * double(channels);
  if (raw_bytes > kMaxVolumeDataBytes) bad_metaimage(path, "DimSize describes more than 4 TiB of voxels");

  for (const char* key : {"ElementSpacing", "ElementSize"})
    if (keys.count(key))
      for (double s : require_numbers(keys, key, ndims, path))
        if (!(s > 0)) bad_metaimage(path, std::string("voxel spacing ") + key + " must be positive, is \"" + keys[key] + "\"");
  for (const char* key : {"Offset", "Origin", "Position", "ImagePosition", "CenterOfRotation"})
    if (keys.count(key))
      for (double o : require_numbers(keys, key, ndims, path))
        if (!(std::abs(o) <= kMaxVolumeCoordinate)) bad_metaimage(path, std::string(key) + " is out of range");
  for (const char* key : {"TransformMatrix", "Rotation", "Orientation"}) {
    if (!keys.count(key)) continue;
    const std::vector<double> m = require_numbers(keys, key, ndims * ndims, path);
    if (ndims == 2 || ndims == 3) {
      // Columns normalised: the axes must span space (ITK inverts the direction matrix). A 2D
      // image's (an X-ray, engine/image_io.hpp) too.
      Eigen::MatrixXd d = Eigen::Map<const Eigen::MatrixXd>(m.data(), Eigen::Index(ndims), Eigen::Index(ndims));
      for (Eigen::Index c = 0; c < d.cols(); ++c) {
        const double n = d.col(c).norm();
        if (!(n > 0)) bad_metaimage(path, std::string(key) + " has a zero axis");
        d.col(c) /= n;
      }
      if (!(std::abs(d.determinant()) > 1e-6)) bad_metaimage(path, std::string(key) + " axes are (nearly) parallel");
    }
  }
  int64_t header_size = 0;
  if (keys.count("HeaderSize"))
    header_size = require_integer("HeaderSize", keys["HeaderSize"], -1, int64_t(kMaxVolumeDataBytes), path);
  bool compressed = false;
  if (keys.count("CompressedData")) {
    const std::string v = to_lower(keys["CompressedData"]);
    if (v != "true" && v != "false") bad_metaimage(path, "CompressedData must be True or False");
    compressed = v == "true";
  }
  const std::string& data_file = keys["ElementDataFile"];
  if (data_file.empty()) bad_metaimage(path, "ElementDataFile is empty");
  for (const char c : data_file)
    if (static_cast<unsigned char>(c) < 0x20) bad_metaimage(path, "ElementDataFile holds control characters");
  // "LIST" and printf-style patterns spread the data over several files: MetaIO checks those,
  // but divides by the pattern's step without looking (SIGFPE on a step of 0; fuzz_volume_mha).
  if (data_file.rfind("LIST", 0) != 0 && data_file.find_first_of(" \t") != std::string::npos) {
    bool ok = false;
    const std::vector<double> range = numbers(data_file.substr(data_file.find_first_of(" \t")), ok);
    if (!ok || range.size() < 3 || range[2] == 0 || (range[1] - range[0]) / range[2] < 0 ||
        (range[1] - range[0]) / range[2] > 1e6)
      bad_metaimage(path, "ElementDataFile is neither a file name nor a \"pattern first last step\" list");
  }
  const bool binary = !(keys.count("BinaryData") && to_lower(keys["BinaryData"]) == "false");
  if (data_file.rfind("LIST", 0) == 0) {
    check_slice_list(path, text, fields, data_file, SliceList{dims, bytes, channels, binary, compressed, header_size});
    return std::nullopt;
  }
  if (!binary) return std::nullopt;  // ASCII voxels: not sized
  double need = raw_bytes;
  if (compressed) {
    // ITK and MetaIO always write it; without it MetaIO sizes its buffer from where it thinks the
    // header ended, and a corrupt header made that 2^64 bytes (fuzz_volume_mha).
    if (!keys.count("CompressedDataSize")) bad_metaimage(path, "compressed data without CompressedDataSize");
    need = double(require_integer("CompressedDataSize", keys["CompressedDataSize"], 1, int64_t(kMaxVolumeDataBytes), path));
    // Deflate inflates at most 1032 to 1: a claim beyond that is refused before anything of its
    // size is allocated (for .mhd data nothing else bounds it).
    if (raw_bytes > 1032.0 * need + 64.0)
      bad_metaimage(path, "DimSize describes " + std::to_string(uint64_t(raw_bytes)) + " bytes of voxels, more than " +
                    std::to_string(uint64_t(need)) + " bytes of compressed data can hold");
  }
  if (header_size < 0) return std::nullopt;  // HeaderSize -1: the data are the file's last bytes

  std::error_code ec;
  const bool local = to_lower(data_file) == "local";
  // total: the bytes after the header (LOCAL) or the data file's; skipped: HeaderSize bytes at the
  // data file's start; have: the data bytes after those.
  uint64_t total = 0, skipped = 0, have = 0;
  if (local) {
    const uint64_t size = fs::file_size(path, ec);
    have = total = size > header_bytes ? size - header_bytes : 0;
  } else {
    if (data_file.find_first_of(" \t") != std::string::npos) return std::nullopt;  // a pattern
    fs::path data = data_file;
    if (data.is_relative()) data = fs::path(path).parent_path() / data;
    if (!fs::is_regular_file(data, ec)) throw_input_error(path, "data file " + data.string() + " not found");
    total = fs::file_size(data, ec);
    skipped = uint64_t(header_size);
    have = total > skipped ? total - skipped : 0;
  }
  if (double(have) < need)
    throw_input_error(path, "file truncated (" + std::to_string(total) + " of the " +
                                std::to_string(uint64_t(need) + skipped) + " bytes its header describes are present)");
  // MetaIO inflates exactly CompressedDataSize bytes and, when they hold fewer voxels than the
  // header describes, leaves the rest of its buffer as it was, without a word (a mutated
  // CompressedDataSize = 1 was read with exit 0 and uninitialised voxels). ITK and MetaIO write
  // the stream's exact length, with nothing after it.
  if (compressed && double(have) != need)
    throw_input_error(path, "CompressedDataSize is " + std::to_string(uint64_t(need)) + " but " + std::to_string(have) +
                                " bytes of compressed data follow");

  // The form ITK writes; anything else is left to ITK's reader. MetaIO takes these three spellings
  // of LOCAL; BinaryData must be stated (MetaIO's default is ASCII for some objects).
  const std::optional<StoredType> type = stored_type(keys["ElementType"]);
  const bool itk_form = (data_file == "LOCAL" || data_file == "Local" || data_file == "local") &&
                        fields.data_line_ended && ndims == 3 && channels == 1 && type &&
                        keys.count("BinaryData") && to_lower(keys["BinaryData"]) == "true" && native_order(keys) &&
                        !keys.count("HeaderSize") && !keys.count("ElementToIntensityFunctionSlope") &&
                        !keys.count("ElementToIntensityFunctionOffset");
  if (!want_voxels || !itk_form) return std::nullopt;
  return MetaImageVoxels{header_bytes, *type, uint64_t(raw_bytes), compressed ? uint64_t(need) : 0};
}

}  // namespace

void check_metaimage_header(const std::string& path) { check_metaimage_file(path, false); }

std::optional<MetaImageVoxels> check_metaimage_header_for_voxels(const std::string& path) { return check_metaimage_file(path, true); }

namespace {

struct FileCloser {
  std::FILE* f;
  ~FileCloser() { std::fclose(f); }
};

// Inflates the zlib (or gzip) stream of layout.compressed_bytes bytes at the file's position into
// dst[0, bytes), as MetaIO does: the output may end before the stream does, not the other way.
void inflate_into(std::FILE* f, const std::string& path, const MetaImageVoxels& layout, unsigned char* dst,
                  size_t bytes) {
  z_stream z{};
  if (inflateInit2(&z, 15 + 32) != Z_OK) throw std::bad_alloc();  // 15 + 32: zlib or gzip header
  struct End {
    z_stream* z;
    ~End() { inflateEnd(z); }
  } end{&z};
  std::vector<unsigned char> chunk(size_t(1) << 20);
  uint64_t left = layout.compressed_bytes;
  size_t done = 0;
  while (done < bytes) {
    if (z.avail_in == 0) {
      if (left == 0) break;
      const size_t n = std::fread(chunk.data(), 1, size_t(std::min<uint64_t>(left, chunk.size())), f);
      if (n == 0) throw_input_error(path, "file truncated (its compressed voxel data end early)");
      left -= n;
      z.next_in = chunk.data();
      z.avail_in = unsigned(n);
    }
    z.next_out = dst + done;
    z.avail_out = unsigned(std::min<size_t>(bytes - done, size_t(1) << 30));
    const size_t before = z.avail_out;
    const int status = inflate(&z, Z_NO_FLUSH);
    done += before - z.avail_out;
    if (status == Z_STREAM_END) break;
    if (status == Z_MEM_ERROR) throw std::bad_alloc();
    if (status != Z_OK && status != Z_BUF_ERROR)
      throw_input_error(path, "corrupt compressed voxel data (zlib: " + std::string(z.msg ? z.msg : "error") + ")");
  }
  if (done < bytes)
    throw_input_error(path, "compressed voxel data hold " + std::to_string(done) + " of the " + std::to_string(bytes) +
                                " bytes the header describes");
}

}  // namespace

VoxelBuffer read_metaimage_voxels(const std::string& path, const MetaImageVoxels& layout, size_t count) {
  if (layout.bytes != uint64_t(count) * uint64_t(stored_type_bytes(layout.type)))
    throw std::invalid_argument("read_metaimage_voxels: the layout does not hold " + std::to_string(count) + " voxels");
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw_input_error(path, "cannot open file");
  FileCloser closer{f};
  if (fseeko(f, off_t(layout.offset), SEEK_SET) != 0) throw_input_error(path, "cannot seek to its voxel data");
  return read_widened(layout.type, count, [&](unsigned char* dst, size_t bytes) {
    if (layout.compressed_bytes > 0) return inflate_into(f, path, layout, dst, bytes);
    // check_metaimage_header_for_voxels has checked the file's length; a file cut since is caught.
    if (std::fread(dst, 1, bytes, f) != bytes) throw_input_error(path, "file truncated (its voxel data end early)");
  });
}

}  // namespace fluoro
