#pragma once
// A float 2D image with a physical pixel spacing, as MetaImage (.mha) or NRRD (.nrrd): the formats
// ITK, 3D Slicer and SimpleITK read with their spacing (a TIFF or PNG has none they honour).
#include <Eigen/Core>
#include <string>

#include "engine/image.hpp"

namespace fluoro {

// True for .mha and .nrrd (single-file formats: a header-and-data pair could not be written
// atomically).
bool is_spaced_image_path(const std::string& path);

// Index (i, j) = pixel (column u, row v), row 0 first; identity direction; spacing_mm = (column
// pitch, row pitch); origin_mm: the physical position of pixel (0, 0)'s centre. Atomic. Throws
// InputError naming the path for another extension or a failed write.
void write_spaced_image(const Image& image, const Eigen::Vector2d& spacing_mm, const Eigen::Vector2d& origin_mm,
                        const std::string& path);

}  // namespace fluoro
