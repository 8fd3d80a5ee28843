#pragma once
// 2D image files: PNG/TIFF (8/16-bit, 32-bit float TIFF), JPEG, BMP and single-frame DICOM through
// ITK's image IO, PFM, and 2D images (or 3D ones a slice thick) in the volume formats, NIfTI
// (.nii/.nii.gz), MetaImage (.mha/.mhd) and NRRD (.nrrd/.nhdr), through volume_io's checked reader
// (read_planar_volume). Row 0 is the top row in every file.
#include <cstdint>
#include <string>
#include <vector>

#include "engine/image.hpp"

namespace cv {
class Mat;
}

namespace fluoro {

// The stored values as float (8/16-bit integers keep their integer values). Multi-channel images
// are converted to grey. Throws InputError naming the path for a missing, unreadable, empty or
// multi-frame file, or NaN pixels.
Image read_image(const std::string& path);

// Raw float values, by extension: .tif/.tiff (32-bit float), .pfm, .nii/.nii.gz. Atomic.
void write_float_image(const Image& image, const std::string& path);

// A display PNG (8-bit grey) mapping [lo, hi] linearly to [0, 255], clamped. Atomic.
void write_png(const Image& image, const std::string& path, float lo, float hi);
// An 8-bit image (grey or RGB interleaved when channels == 3) as PNG. Atomic.
void write_png_u8(const std::vector<uint8_t>& pixels, int width, int height, int channels,
                  const std::string& path);

// A 16-bit grey PNG. Atomic.
void write_png_u16(const std::vector<uint16_t>& pixels, int width, int height, const std::string& path);

// The pixels as stored in a PNG, TIFF, JPEG or BMP file (8/16-bit or float, 1-4 channels in the
// file's order), for commands that write an image back with the type it came with. Throws
// InputError naming the path.
cv::Mat read_stored_image(const std::string& path);
// Writes such an image by extension: 8-bit to any of those formats, 16-bit to .png/.tif, float to
// .tif; another combination throws InputError naming the path. Atomic.
void write_stored_image(const cv::Mat& image, const std::string& path);

// True for the extensions write_float_image takes.
bool is_float_image_path(const std::string& path);

}  // namespace fluoro
