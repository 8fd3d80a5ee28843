#include "engine/dicom_file_check.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <optional>
#include <set>
#include <string>

#include "engine/error.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

constexpr uint64_t kPreambleBytes = 128;
constexpr uint32_t kUndefinedLength = 0xFFFFFFFF;
constexpr int kMaxSequenceDepth = 16;
// Compressed pixel data may decode to at most this many times the file's bytes: the bound
// read_volume puts on every format (deflate's 1032:1, and up to 4 bytes a voxel as float).
constexpr double kMaxExpansion = 1032.0 * 4.0;

constexpr uint16_t kItemGroup = 0xFFFE;
constexpr uint16_t kItem = 0xE000;
constexpr uint16_t kItemDelimiter = 0xE00D;
constexpr uint16_t kSequenceDelimiter = 0xE0DD;

// Value representations of PS3.5 6.2; those of the second set carry a 4-byte length (after two
// reserved bytes) in explicit VR, the others a 2-byte one.
const std::set<std::string>& known_vrs() {
  static const std::set<std::string> vrs = {"AE", "AS", "AT", "CS", "DA", "DS", "DT", "FD", "FL", "IS", "LO",
                                            "LT", "OB", "OD", "OF", "OL", "OV", "OW", "PN", "SH", "SL", "SQ",
                                            "SS", "ST", "SV", "TM", "UC", "UI", "UL", "UN", "UR", "US", "UT", "UV"};
  return vrs;
}
bool has_long_length(const std::string& vr) {
  static const std::set<std::string> vrs = {"OB", "OD", "OF", "OL", "OV", "OW", "SQ", "SV", "UC", "UN", "UR", "UT", "UV"};
  return vrs.count(vr) > 0;
}

std::string tag_text(uint16_t group, uint16_t element) {
  char text[16];
  std::snprintf(text, sizeof text, "(%04X,%04X)", unsigned(group), unsigned(element));
  return text;
}

struct Element {
  uint16_t group = 0, element = 0;
  std::string vr;  // empty in implicit VR and for the item and delimiter tags
  uint32_t length = 0;
  uint64_t start = 0, value = 0;  // where the element and its value begin
};

// Walks the data elements from the file, reading their headers and skipping their values, with
// every length checked against the end of what holds the element (the file, a sequence, an item).
class DicomWalk {
 public:
  explicit DicomWalk(const std::string& path) : path_(path), in_(path, std::ios::binary) {
    std::error_code ec;
    size_ = fs::file_size(path, ec);
    if (ec || !in_) bad("cannot open the file");
  }

  void run() {
    std::array<char, 4> magic{};
    if (size_ < kPreambleBytes + 4 || !read_at(kPreambleBytes, magic.data(), 4) ||
        std::string(magic.data(), 4) != "DICM")
      bad("no DICM magic after the 128-byte preamble (not a DICOM Part 10 file)");
    pos_ = kPreambleBytes + 4;
    read_file_meta();
    walk_data_set(size_, 0, /*top=*/true, /*in_undefined_item=*/false);
    check_pixel_data();
  }

 private:
  [[noreturn]] void bad(const std::string& problem) const { throw_input_error(path_, "DICOM file: " + problem); }

  bool read_at(uint64_t at, char* out, size_t n) {
    in_.clear();
    in_.seekg(std::streamoff(at));
    in_.read(out, std::streamsize(n));
    return bool(in_);
  }
  uint16_t u16(const unsigned char* b, bool big) const {
    return big ? uint16_t(b[0] << 8 | b[1]) : uint16_t(b[1] << 8 | b[0]);
  }
  uint32_t u32(const unsigned char* b, bool big) const {
    return big ? uint32_t(b[0]) << 24 | uint32_t(b[1]) << 16 | uint32_t(b[2]) << 8 | b[3]
               : uint32_t(b[3]) << 24 | uint32_t(b[2]) << 16 | uint32_t(b[1]) << 8 | b[0];
  }

  // The element header at pos_, which must lie before `end`; leaves pos_ at its value.
  Element read_header(uint64_t end, bool explicit_vr, bool big) {
    Element e;
    e.start = pos_;
    unsigned char b[12];
    if (pos_ + 8 > end || !read_at(pos_, reinterpret_cast<char*>(b), 8))
      bad("the data element at byte " + std::to_string(pos_) + " runs past the end of " + container(end));
    // The File Meta Information (group 0002) is always little endian.
    const bool meta = u16(b, false) == 0x0002;
    e.group = u16(b, big && !meta);
    e.element = u16(b + 2, big && !meta);
    const bool be = big && !meta;
    if (e.group == kItemGroup || !explicit_vr) {
      e.length = u32(b + 4, be);
      e.value = pos_ + 8;
    } else {
      e.vr = std::string(reinterpret_cast<char*>(b + 4), 2);
      if (!known_vrs().count(e.vr))
        bad("the data element " + tag_text(e.group, e.element) + " at byte " + std::to_string(pos_) +
            " has no valid value representation");
      if (has_long_length(e.vr)) {
        if (pos_ + 12 > end || !read_at(pos_ + 8, reinterpret_cast<char*>(b + 8), 4))
          bad("the data element at byte " + std::to_string(pos_) + " runs past the end of " + container(end));
        e.length = u32(b + 8, be);
        e.value = pos_ + 12;
      } else {
        e.length = u16(b + 6, be);
        e.value = pos_ + 8;
      }
    }
    pos_ = e.value;
    return e;
  }

  std::string container(uint64_t end) const {
    return end == size_ ? "the file (" + std::to_string(size_) + " bytes)"
                        : "its sequence item (which ends at byte " + std::to_string(end) + ")";
  }

  // A defined length must fit in what holds the element.
  void check_fits(const Element& e, uint64_t end) {
    if (e.value + e.length > end)
      bad("the data element " + tag_text(e.group, e.element) + " at byte " + std::to_string(e.start) +
          " states a length of " + std::to_string(e.length) + " bytes, past the end of " + container(end));
  }

  // Group 0002, explicit VR little endian; its Transfer Syntax UID says how the rest is encoded.
  void read_file_meta() {
    std::string syntax;
    bool any = false;
    while (pos_ + 2 <= size_) {
      unsigned char g[2];
      if (!read_at(pos_, reinterpret_cast<char*>(g), 2) || u16(g, false) != 0x0002) break;
      const Element e = read_header(size_, true, false);
      if (e.length == kUndefinedLength)
        bad("the File Meta Information element " + tag_text(e.group, e.element) + " has an undefined length");
      check_fits(e, size_);
      if (e.element == 0x0000 && e.length == 4) {
        // The group's length: GDCM asserts when the group ends before it says (a truncated meta).
        unsigned char b[4];
        if (read_at(e.value, reinterpret_cast<char*>(b), 4) && e.value + 4 + u32(b, false) > size_)
          bad("the File Meta Information's group length (0002,0000) says " + std::to_string(u32(b, false)) +
              " bytes, past the end of the file (" + std::to_string(size_) + " bytes)");
      }
      if (e.element == 0x0010 && e.length <= 64) {
        std::string text(e.length, '\0');
        if (e.length > 0) read_at(e.value, text.data(), e.length);
        while (!text.empty() && (text.back() == '\0' || text.back() == ' ')) text.pop_back();
        syntax = text;
      }
      pos_ = e.value + e.length;
      any = true;
    }
    if (!any) bad("no File Meta Information (group 0002) after the DICM magic");
    if (pos_ >= size_) bad("no data set after the File Meta Information");
    if (syntax == "1.2.840.10008.1.2.1.99")
      bad("deflated data sets (transfer syntax 1.2.840.10008.1.2.1.99) are not supported");
    big_endian_ = syntax == "1.2.840.10008.1.2.2";
    explicit_vr_ = syntax != "1.2.840.10008.1.2";
    // A data set declared explicit whose first element carries no VR is implicit (GDCM reads such
    // files the same way).
    if (explicit_vr_ && !big_endian_ && pos_ + 6 <= size_) {
      char vr[2];
      if (read_at(pos_ + 4, vr, 2) && !known_vrs().count(std::string(vr, 2))) explicit_vr_ = false;
    }
  }

  // Elements from pos_ to `end`, or up to an item delimiter when the item has an undefined length.
  void walk_data_set(uint64_t end, int depth, bool top, bool in_undefined_item, std::optional<bool> explicit_vr = {}) {
    const bool explicit_now = explicit_vr.value_or(explicit_vr_);
    while (pos_ < end) {
      const Element e = read_header(end, explicit_now, big_endian_);
      if (e.group == kItemGroup) {
        if (e.element == kItemDelimiter && in_undefined_item) return;
        bad("unexpected item tag " + tag_text(e.group, e.element) + " at byte " + std::to_string(e.start));
      }
      const bool pixel_data = top && e.group == 0x7FE0 && e.element == 0x0010;
      check_pixel_data_vr(e);
      if (e.length == kUndefinedLength) {
        if (pixel_data) {
          walk_fragments(end);
        } else if (e.vr.empty() || e.vr == "SQ" || e.vr == "UN") {
          // An undefined-length UN holds implicit VR little endian items (PS3.5 6.2.2).
          walk_items(end, depth + 1, std::nullopt, e.vr == "UN" ? false : explicit_now);
        } else {
          bad("the data element " + tag_text(e.group, e.element) + " at byte " + std::to_string(e.start) +
              " has an undefined length but is not a sequence");
        }
        continue;
      }
      check_fits(e, end);
      if (e.vr == "SQ" || ((e.vr.empty() || e.vr == "UN") && starts_with_item(e))) {
        pos_ = e.value;
        walk_items(e.value + e.length, depth + 1, e.value + e.length,
                   e.vr == "UN" ? false : explicit_now);
      }
      if (top) {
        check_image_attribute(e);
        note_image_value(e);
        check_recognition_code(e);
      }
      if (pixel_data) pixel_bytes_ = e.length;
      pos_ = e.value + e.length;
    }
    if (in_undefined_item) bad("a sequence item has no item delimiter before the end of " + container(end));
  }

  bool starts_with_item(const Element& e) {
    unsigned char b[4];
    return e.length >= 8 && read_at(e.value, reinterpret_cast<char*>(b), 4) && u16(b, big_endian_) == kItemGroup &&
           u16(b + 2, big_endian_) == kItem;
  }

  // The items of a sequence: up to `defined_end` for a defined length, else up to the sequence
  // delimiter (before `end`).
  void walk_items(uint64_t end, int depth, std::optional<uint64_t> defined_end, bool explicit_vr) {
    if (depth > kMaxSequenceDepth) bad("sequences nested more than " + std::to_string(kMaxSequenceDepth) + " deep");
    while (!defined_end || pos_ < *defined_end) {
      const Element item = read_header(end, false, big_endian_);
      if (!defined_end && item.group == kItemGroup && item.element == kSequenceDelimiter) return;
      if (item.group != kItemGroup || item.element != kItem)
        bad("a sequence holds " + tag_text(item.group, item.element) + " at byte " + std::to_string(item.start) +
            " where an item belongs");
      if (item.length == kUndefinedLength) {
        walk_data_set(end, depth, false, true, explicit_vr);
      } else {
        check_fits(item, end);
        walk_data_set(item.value + item.length, depth, false, false, explicit_vr);
        pos_ = item.value + item.length;
      }
    }
  }

  // Encapsulated (compressed) pixel data: items of bytes up to the sequence delimiter.
  void walk_fragments(uint64_t end) {
    encapsulated_ = true;
    pixel_bytes_ = 0;
    for (;;) {
      const Element item = read_header(end, false, big_endian_);
      if (item.group == kItemGroup && item.element == kSequenceDelimiter) return;
      if (item.group != kItemGroup || item.element != kItem || item.length == kUndefinedLength)
        bad("the compressed pixel data holds " + tag_text(item.group, item.element) + " at byte " +
            std::to_string(item.start) + " where a fragment belongs");
      check_fits(item, end);
      *pixel_bytes_ += item.length;
      pos_ = item.value + item.length;
    }
  }

  // The image attributes GDCM reads through its typed gdcm::Attribute: it asserts that an
  // explicit VR matches the standard's, and Debian's GDCM keeps its assertions (Columns as
  // another VR aborted the program: fuzz_volume_dcm). Their VRs (PS3.6), and US values of one
  // 2-byte number each (VM 1).
  void check_image_attribute(const Element& e) {
    struct Attribute {
      uint16_t group, element;
      const char* vr;
    };
    static const Attribute attributes[] = {
        {0x0008, 0x0016, "UI"}, {0x0008, 0x0018, "UI"}, {0x0008, 0x0060, "CS"}, {0x0018, 0x0050, "DS"},
        {0x0018, 0x0088, "DS"}, {0x0018, 0x1164, "DS"}, {0x0020, 0x0013, "IS"}, {0x0020, 0x0032, "DS"},
        {0x0020, 0x0037, "DS"}, {0x0028, 0x0002, "US"}, {0x0028, 0x0004, "CS"}, {0x0028, 0x0006, "US"},
        {0x0028, 0x0008, "IS"}, {0x0028, 0x0009, "AT"}, {0x0028, 0x0010, "US"}, {0x0028, 0x0011, "US"},
        {0x0028, 0x0030, "DS"}, {0x0028, 0x0034, "IS"}, {0x0028, 0x0100, "US"}, {0x0028, 0x0101, "US"},
        {0x0028, 0x0102, "US"}, {0x0028, 0x0103, "US"}, {0x0028, 0x1050, "DS"}, {0x0028, 0x1051, "DS"},
        {0x0028, 0x1052, "DS"}, {0x0028, 0x1053, "DS"}, {0x0028, 0x1054, "LO"}};
    for (const Attribute& a : attributes) {
      if (a.group != e.group || a.element != e.element) continue;
      if (!e.vr.empty() && e.vr != a.vr)
        bad("the data element " + tag_text(e.group, e.element) + " at byte " + std::to_string(e.start) + " has VR " +
            e.vr + ", the standard's is " + a.vr);
      if (std::string(a.vr) == "US" && e.length != 2)
        bad("the data element " + tag_text(e.group, e.element) + " at byte " + std::to_string(e.start) +
            " holds " + std::to_string(e.length) + " bytes, not one 2-byte number");
      return;
    }
  }

  // Pixel Data is OB or OW (PS3.5 8.2; UN when a file was relayed without its dictionary). GDCM
  // asserts that a sequence (SQ) is not Pixel Data, at any depth: a fuzzed VR aborted the program
  // (CI's fuzz_volume_dcm run of 2026-12-07).
  void check_pixel_data_vr(const Element& e) const {
    if (e.group != 0x7FE0 || e.element != 0x0010 || e.vr.empty()) return;
    if (e.vr != "OB" && e.vr != "OW" && e.vr != "UN")
      bad("the Pixel Data (7FE0,0010) at byte " + std::to_string(e.start) + " has VR " + e.vr + ", not OB or OW");
  }

  // ACR-NEMA's Recognition Code (0008,0010), retired: GDCM, when it does not know the file's SOP
  // class, asserts that a non-empty one starts with "ACR-NEMA", "ACRNEMA" or "MIPS 2.0", and
  // Debian's GDCM keeps its assertions: any other value aborted the program (fuzz_volume_dcm).
  void check_recognition_code(const Element& e) {
    if (e.group != 0x0008 || e.element != 0x0010 || e.length == 0) return;
    char text[8] = {};
    const bool read = e.vr != "SQ" && e.length >= 7 && read_at(e.value, text, std::min<uint32_t>(e.length, 8));
    const std::string value(text, read ? std::min<uint32_t>(e.length, 8) : 0);
    if (!read || !(value.rfind("ACR-NEMA", 0) == 0 || value.rfind("ACRNEMA", 0) == 0 || value.rfind("MIPS 2.0", 0) == 0))
      bad("the Recognition Code (0008,0010) at byte " + std::to_string(e.start) +
          " is not ACR-NEMA's (\"ACR-NEMA\", \"ACRNEMA\" or \"MIPS 2.0\")");
  }

  // Rows, Columns, Samples per Pixel, Bits Allocated (US) and Number of Frames (IS).
  void note_image_value(const Element& e) {
    if (e.group != 0x0028) return;
    auto us = [&]() -> std::optional<uint32_t> {
      unsigned char b[2];
      if (e.length != 2 || !read_at(e.value, reinterpret_cast<char*>(b), 2)) return std::nullopt;
      return u16(b, big_endian_);
    };
    switch (e.element) {
      case 0x0010: rows_ = us(); break;
      case 0x0011: columns_ = us(); break;
      case 0x0002: samples_ = us(); break;
      case 0x0100: bits_allocated_ = us(); break;
      case 0x0101: bits_stored_ = us(); break;
      case 0x0102: high_bit_ = us(); break;
      case 0x0103: pixel_representation_ = us(); break;
      case 0x0004:
        if (e.length <= 64) {
          photometric_ = std::string(e.length, '\0');
          if (e.length > 0) read_at(e.value, photometric_->data(), e.length);
          while (!photometric_->empty() && (photometric_->back() == ' ' || photometric_->back() == '\0'))
            photometric_->pop_back();
          // The value goes into the one-line message: no control characters (a fuzzed newline).
          for (char& c : *photometric_)
            if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) > 0x7E) c = '?';
        } else {
          photometric_ = "(too long)";
        }
        break;
      case 0x0008:
        if (e.length > 0 && e.length <= 16) {
          std::string text(e.length, '\0');
          if (read_at(e.value, text.data(), e.length)) {
            try {
              const long long n = std::stoll(text);
              if (n > 0) frames_ = uint64_t(n);
            } catch (const std::exception&) {  // not a number: GDCM's business
            }
          }
        }
        break;
      default: break;
    }
  }

  // GDCM's PixelFormat asserts on values outside what it can hold (Samples per Pixel 256 aborted
  // the program, in a file without pixel data: fuzz_volume_dcm); the standard's values are
  // narrower still (PS3.3 C.7.6.3).
  void check_pixel_format() const {
    const auto refuse = [this](const std::string& what, uint32_t value) {
      bad(what + " is " + std::to_string(value) + ", which no DICOM image has");
    };
    if (samples_ && *samples_ != 1 && *samples_ != 3 && *samples_ != 4) refuse("Samples per Pixel (0028,0002)", *samples_);
    if (bits_allocated_ && !(*bits_allocated_ == 1 || *bits_allocated_ == 12 ||
                             (*bits_allocated_ % 8 == 0 && *bits_allocated_ >= 8 && *bits_allocated_ <= 64)))
      refuse("Bits Allocated (0028,0100)", *bits_allocated_);
    if (bits_stored_ && (*bits_stored_ == 0 || (bits_allocated_ && *bits_stored_ > *bits_allocated_)))
      refuse("Bits Stored (0028,0101)", *bits_stored_);
    if (high_bit_ && bits_stored_ && *high_bit_ + 1 != *bits_stored_) refuse("High Bit (0028,0102)", *high_bit_);
    if (pixel_representation_ && *pixel_representation_ > 1)
      refuse("Pixel Representation (0028,0103)", *pixel_representation_);
  }

  // An image's pixel description must be whole before GDCM reads it, and its Photometric
  // Interpretation one of the standard's, checked whether or not the file has pixel data: GDCM
  // takes any prefix of a name for the name ("PALETTE COLO" is PALETTE COLOR to it) and asserts on
  // a palette image without its lookup tables even when there are no pixels (fuzz_volume_dcm).
  // PALETTE COLOR is refused outright: no X-ray or CT is one, and GDCM's palette path is where
  // its assertions are.
  void check_pixel_data() const {
    check_pixel_format();
    static const std::set<std::string> photometrics = {"MONOCHROME1", "MONOCHROME2", "RGB", "YBR_FULL", "YBR_FULL_422",
                                                       "YBR_PARTIAL_422", "YBR_PARTIAL_420", "YBR_ICT", "YBR_RCT"};
    if (photometric_ && *photometric_ == "PALETTE COLOR")
      bad("a PALETTE COLOR image (Photometric Interpretation (0028,0004)): X-rays and CTs are MONOCHROME1 or MONOCHROME2");
    if (photometric_ && !photometrics.count(*photometric_))
      bad("the Photometric Interpretation (0028,0004) \"" + *photometric_ + "\" is none of the standard's");
    if (!pixel_bytes_) return;
    if (!rows_ || !columns_ || !bits_allocated_)
      bad("the image lacks Rows (0028,0010), Columns (0028,0011) or Bits Allocated (0028,0100), each one 2-byte value");
    const double described = double(*rows_) * double(*columns_) * double(samples_.value_or(1)) *
                             double(frames_.value_or(1)) * double(*bits_allocated_) / 8.0;
    const std::string what = "Rows, Columns, Bits Allocated" + std::string(frames_ ? " and Number of Frames" : "") +
                             " describe " + std::to_string(uint64_t(described)) + " bytes of pixels";
    if (!encapsulated_ && double(*pixel_bytes_) < described)
      bad("the pixel data holds " + std::to_string(*pixel_bytes_) + " bytes, but " + what);
    if (encapsulated_ && described > kMaxExpansion * double(size_))
      bad(what + ", more than a " + std::to_string(size_) + "-byte file can hold");
  }

  std::string path_;
  std::ifstream in_;
  uint64_t size_ = 0;
  uint64_t pos_ = 0;
  bool explicit_vr_ = true, big_endian_ = false, encapsulated_ = false;
  std::optional<uint32_t> rows_, columns_, samples_, bits_allocated_, bits_stored_, high_bit_, pixel_representation_;
  std::optional<uint64_t> frames_, pixel_bytes_;
  std::optional<std::string> photometric_;
};

}  // namespace

void check_dicom_file(const std::string& path) { DicomWalk(path).run(); }

bool has_dicom_magic(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char bytes[kPreambleBytes + 4];
  return in.read(bytes, sizeof bytes) && std::string(bytes + kPreambleBytes, 4) == "DICM";
}

}  // namespace fluoro
