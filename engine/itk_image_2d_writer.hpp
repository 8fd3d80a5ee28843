#pragma once
// Engine-internal: a float Image written through an ITK image IO (NIfTI, MetaImage, NRRD), not
// copied, shared by image_io's NIfTI output and the spaced .mha/.nrrd writer.
#include <itkImageIOBase.h>

#include <Eigen/Core>
#include <string>

#include "engine/image.hpp"

namespace fluoro::detail {

// Index (i, j) = pixel (column, row), row 0 first; identity direction. Writes `file` itself (the
// caller makes it atomic); throws std::runtime_error with ITK's description on failure.
void write_itk_image_2d(const Image& image, const Eigen::Vector2d& spacing_mm, const Eigen::Vector2d& origin_mm,
                        itk::ImageIOBase* io, const std::string& file);

}  // namespace fluoro::detail
