#pragma once
// PNG encoding through libpng directly, for the settings ITK's PNGImageIO does not expose.
// The panorama is written on the clock (the whole `fluoro panorama` command has a time goal), and
// libpng's default adaptive filtering (all five filters tried on every row) with zlib's default
// strategy took 0.24 s of CPU for a 4465 x 1058 16-bit panorama. The Sub filter with run-length
// matching (Z_RLE) takes 0.09 s and gives a slightly smaller file on such images (5.64 MB
// against 5.85 MB): X-ray images change slowly along a row, so the left-neighbour differences are
// small numbers with long runs.
#include <string>

namespace fluoro {

// Writes `height` rows of `width` pixels of `channels` (1 grey, 2 grey + alpha, 3 RGB, 4 RGBA)
// interleaved 8- or 16-bit (`bit_depth`; 16-bit in the host's byte order) samples to `file`.
// Throws std::runtime_error naming the file when it cannot be written.
void write_png_file(const void* data, int width, int height, int channels, int bit_depth, const std::string& file);

}  // namespace fluoro
