#include "engine/png_writer.hpp"

#include <png.h>
#include <zlib.h>

#include <bit>
#include <cstdio>
#include <stdexcept>
#include <vector>

namespace fluoro {
namespace {

// libpng reports errors by longjmp: this frame holds no C++ object with a destructor between the
// setjmp and the calls that may jump, so nothing is skipped; false on any libpng error.
bool encode(std::FILE* out, png_bytep* rows, int width, int height, int colour_type, int bit_depth) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  if (!png) return false;
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_init_io(png, out);
  png_set_IHDR(png, info, png_uint_32(width), png_uint_32(height), bit_depth, colour_type, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB);
  png_set_compression_level(png, 1);
  png_set_compression_strategy(png, Z_RLE);
  png_write_info(png, info);
  if (bit_depth == 16 && std::endian::native == std::endian::little) png_set_swap(png);  // PNG stores big-endian
  png_write_image(png, rows);
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

void write_png_file(const void* data, int width, int height, int channels, int bit_depth, const std::string& file) {
  if (width <= 0 || height <= 0 || channels < 1 || channels > 4 || (bit_depth != 8 && bit_depth != 16))
    throw std::invalid_argument("write_png_file: 1-4 channels of 8 or 16 bits and a non-empty image");
  static constexpr int kColourType[] = {PNG_COLOR_TYPE_GRAY, PNG_COLOR_TYPE_GRAY_ALPHA, PNG_COLOR_TYPE_RGB,
                                        PNG_COLOR_TYPE_RGB_ALPHA};
  const size_t row_bytes = size_t(width) * size_t(channels) * size_t(bit_depth / 8);
  std::vector<png_bytep> rows(static_cast<size_t>(height));
  for (int y = 0; y < height; ++y)
    rows[size_t(y)] = const_cast<png_bytep>(static_cast<const png_byte*>(data) + size_t(y) * row_bytes);
  std::FILE* out = std::fopen(file.c_str(), "wb");
  if (!out) throw std::runtime_error(file + ": cannot write image");
  const bool encoded = encode(out, rows.data(), width, height, kColourType[channels - 1], bit_depth);
  const bool flushed = std::fflush(out) == 0 && !std::ferror(out);
  const bool closed = std::fclose(out) == 0;
  if (!encoded || !flushed || !closed) throw std::runtime_error(file + ": cannot write image");
}

}  // namespace fluoro
