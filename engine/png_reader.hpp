#pragma once
// PNG decoding through libpng directly. ITK 5.2's PNGImageIO lets libpng print "libpng error: ..."
// to stderr and, for a corrupt header, abort the process (its reader sets no jump buffer for some
// errors); here every libpng error and warning is kept and becomes one InputError.
#include <cstdint>
#include <string>
#include <vector>

namespace fluoro {

struct PngPixels {
  int width = 0, height = 0;
  int channels = 0;   // 1 grey, 2 grey + alpha, 3 RGB, 4 RGBA (palettes expanded to RGB(A))
  int bit_depth = 0;  // 8 or 16 (grey of 1, 2 or 4 bits is widened to 8)
  std::vector<uint8_t> bytes;  // rows top to bottom, components interleaved, 16-bit in native order
};

// Throws InputError naming the path for a file that is not a complete, valid PNG, or whose
// decoded pixels would exceed 1 GiB.
PngPixels read_png_file(const std::string& path);

}  // namespace fluoro
