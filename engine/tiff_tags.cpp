#include "engine/tiff_tags.hpp"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <vector>

#include "engine/error.hpp"

namespace fluoro {
namespace {

constexpr uint16_t kDateTime = 306, kAscii = 2;
constexpr uint64_t kDateTimeBytes = 20;  // "YYYY:MM:DD HH:MM:SS" and its NUL

class Bytes {
 public:
  Bytes(std::vector<unsigned char> data, bool big_endian) : data_(std::move(data)), big_(big_endian) {}
  bool has(uint64_t offset, uint64_t size) const { return offset <= data_.size() && size <= data_.size() - offset; }
  uint64_t get(uint64_t offset, int size) const {  // caller checked has(offset, size)
    uint64_t v = 0;
    for (int i = 0; i < size; ++i) {
      const uint64_t byte = data_[offset + uint64_t(big_ ? i : size - 1 - i)];
      v = (v << 8) | byte;
    }
    return v;
  }
  const unsigned char* at(uint64_t offset) const { return data_.data() + offset; }

 private:
  std::vector<unsigned char> data_;
  bool big_;
};

}  // namespace

void check_tiff_tags(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<unsigned char> data{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (data.size() < 8 || !((data[0] == 'I' && data[1] == 'I') || (data[0] == 'M' && data[1] == 'M'))) return;
  const bool big_endian = data[0] == 'M';
  const Bytes b(std::move(data), big_endian);
  const uint64_t version = b.get(2, 2);
  if (version != 42 && version != 43) return;
  const bool big_tiff = version == 43;
  // Classic: 4-byte offsets, 2-byte entry count, 12-byte entries with the value inline up to 4
  // bytes. BigTIFF: 8-byte offsets and counts, 20-byte entries, values inline up to 8 bytes.
  const int offset_size = big_tiff ? 8 : 4, count_size = big_tiff ? 8 : 2, entry_size = big_tiff ? 20 : 12;
  const uint64_t first = big_tiff ? (b.has(8, 8) ? b.get(8, 8) : 0) : b.get(4, 4);
  if (!b.has(first, uint64_t(count_size))) return;
  const uint64_t entries = b.get(first, count_size);
  for (uint64_t e = 0; e < entries; ++e) {
    const uint64_t entry = first + uint64_t(count_size) + e * uint64_t(entry_size);
    if (!b.has(entry, uint64_t(entry_size))) return;
    if (b.get(entry, 2) != kDateTime || b.get(entry + 2, 2) != kAscii) continue;
    const uint64_t count = b.get(entry + 4, offset_size);
    const uint64_t value = entry + 4 + uint64_t(offset_size);
    const uint64_t where = count <= uint64_t(offset_size) ? value : b.get(value, offset_size);
    bool ok = count >= kDateTimeBytes && b.has(where, kDateTimeBytes);
    if (ok) ok = std::memchr(b.at(where), 0, kDateTimeBytes - 1) == nullptr;
    if (!ok) throw_input_error(path, "corrupt TIFF: the DateTime tag is not a 19-character date and time");
  }
}

}  // namespace fluoro
