#include "engine/png_reader.hpp"

#include <png.h>

#include <bit>
#include <csetjmp>
#include <cstdio>
#include <new>
#include <vector>
#include <cstring>

#include "engine/error.hpp"

namespace fluoro {
namespace {

constexpr size_t kMaxDecodedBytes = size_t(1) << 30;

// libpng's error callback must not return: it records the message and jumps back to the setjmp
// of the decode phase that is running.
struct ErrorState {
  char message[200] = "corrupt PNG";
};

void on_error(png_structp png, png_const_charp message) {
  auto* state = static_cast<ErrorState*>(png_get_error_ptr(png));
  std::snprintf(state->message, sizeof state->message, "%s", message);
  png_longjmp(png, 1);
}
void on_warning(png_structp, png_const_charp) {}  // benign (e.g. an unknown ancillary chunk)

// The two decode phases hold no C++ object with a destructor between setjmp and the libpng calls
// that may jump, so a longjmp skips nothing. Each returns false on a libpng error.
bool read_header(png_structp png, png_infop info, std::FILE* file, PngPixels& out) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_init_io(png, file);
  png_set_user_limits(png, 1u << 16, 1u << 16);  // pixels per side; the total is checked after
  png_read_info(png, info);
  const int colour = png_get_color_type(png, info);
  const int depth = png_get_bit_depth(png, info);
  // As ITK's PNGImageIO reads them: palettes to RGB, low-bit grey to 8 bits, tRNS to alpha.
  if (colour == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if (colour == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
  if (png_get_valid(png, info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(png);
  if (depth == 16 && std::endian::native == std::endian::little) png_set_swap(png);  // PNG stores big-endian
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  out.width = int(png_get_image_width(png, info));
  out.height = int(png_get_image_height(png, info));
  out.channels = png_get_channels(png, info);
  out.bit_depth = png_get_bit_depth(png, info);
  return true;
}

bool read_rows(png_structp png, png_infop info, png_bytep* rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_read_image(png, rows);
  png_read_end(png, nullptr);  // reads (and CRC-checks) up to IEND: a cut-off file fails here
  (void)info;
  return true;
}

struct Decoder {
  std::FILE* file = nullptr;
  png_structp png = nullptr;
  png_infop info = nullptr;
  ~Decoder() {
    if (png) png_destroy_read_struct(&png, info ? &info : nullptr, nullptr);
    if (file) std::fclose(file);
  }
};

}  // namespace

PngPixels read_png_file(const std::string& path) {
  Decoder d;
  d.file = std::fopen(path.c_str(), "rb");
  if (!d.file) throw_input_error(path, "cannot open file");
  unsigned char signature[8] = {};
  if (std::fread(signature, 1, 8, d.file) != 8 || png_sig_cmp(signature, 0, 8) != 0)
    throw_input_error(path, "cannot read image (not a PNG file: bad signature)");
  ErrorState state;
  d.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &state, on_error, on_warning);
  if (!d.png || !(d.info = png_create_info_struct(d.png))) throw std::bad_alloc();
  png_set_sig_bytes(d.png, 8);
  PngPixels out;
  if (!read_header(d.png, d.info, d.file, out))
    throw_input_error(path, std::string("cannot read image (corrupt PNG header: ") + state.message + ")");
  const size_t row_bytes = size_t(out.width) * size_t(out.channels) * size_t(out.bit_depth / 8);
  if (out.width <= 0 || out.height <= 0) throw_input_error(path, "empty image (0 pixels)");
  if (row_bytes * size_t(out.height) > kMaxDecodedBytes)
    throw_input_error(path, "PNG of " + std::to_string(out.width) + " x " + std::to_string(out.height) +
                                " pixels is larger than 1 GiB decoded");
  if (row_bytes != png_get_rowbytes(d.png, d.info)) throw_input_error(path, "unsupported PNG layout");
  out.bytes.resize(row_bytes * size_t(out.height));
  std::vector<png_bytep> rows(size_t(out.height));
  for (size_t r = 0; r < rows.size(); ++r) rows[r] = out.bytes.data() + r * row_bytes;
  if (!read_rows(d.png, d.info, rows.data())) {
    // libpng's "Read Error" is its read callback finding the end of the file.
    if (std::strcmp(state.message, "Read Error") == 0) throw_input_error(path, "cannot read image (file truncated)");
    throw_input_error(path, std::string("cannot read image (corrupt PNG data: ") + state.message + ")");
  }
  return out;
}

}  // namespace fluoro
