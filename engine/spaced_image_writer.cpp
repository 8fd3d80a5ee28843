#include "engine/spaced_image_writer.hpp"

#include <itkImage.h>
#include <itkImageFileWriter.h>
#include <itkMetaImageIO.h>
#include <itkNrrdImageIO.h>

#include <stdexcept>

#include "engine/atomic_file.hpp"
#include "engine/error.hpp"
#include "engine/file_names.hpp"
#include "engine/itk_image_2d_writer.hpp"

namespace fluoro {

bool is_spaced_image_path(const std::string& path) {
  const std::string ext = lower_extension(path);
  return ext == ".mha" || ext == ".nrrd";
}

namespace detail {

void write_itk_image_2d(const Image& image, const Eigen::Vector2d& spacing_mm, const Eigen::Vector2d& origin_mm,
                        itk::ImageIOBase* io, const std::string& file) {
  using ItkImage = itk::Image<float, 2>;
  auto itk_image = ItkImage::New();
  ItkImage::SizeType size;
  size[0] = itk::SizeValueType(image.width);
  size[1] = itk::SizeValueType(image.height);
  itk_image->SetRegions(ItkImage::RegionType(size));
  const double spacing[2] = {spacing_mm.x(), spacing_mm.y()}, origin[2] = {origin_mm.x(), origin_mm.y()};
  itk_image->SetSpacing(spacing);
  itk_image->SetOrigin(origin);
  // Not copied: the writer only reads the buffer.
  itk_image->GetPixelContainer()->SetImportPointer(const_cast<float*>(image.pixels.data()), image.pixels.size(), false);
  auto writer = itk::ImageFileWriter<ItkImage>::New();
  writer->SetImageIO(io);
  writer->SetFileName(file);
  writer->SetInput(itk_image);
  try {
    writer->Update();
  } catch (const itk::ExceptionObject& e) {
    throw std::runtime_error(file + ": ITK image writer: " + e.GetDescription());
  }
}

}  // namespace detail

void write_spaced_image(const Image& image, const Eigen::Vector2d& spacing_mm, const Eigen::Vector2d& origin_mm,
                        const std::string& path) {
  if (!is_spaced_image_path(path)) throw_input_error(path, "unsupported extension (use .mha or .nrrd)");
  if (image.width <= 0 || image.height <= 0 || image.pixels.size() != size_t(image.width) * size_t(image.height))
    throw std::invalid_argument("write_spaced_image: pixel buffer does not match width x height");
  if (!(spacing_mm.array() > 0).all() || !spacing_mm.allFinite() || !origin_mm.allFinite())
    throw std::invalid_argument("write_spaced_image: spacing must be positive, the origin finite");
  // The IO chosen here, not by ITK's factories: the extension is already checked.
  const bool meta = lower_extension(path) == ".mha";
  write_file_atomic(path, [&](const std::string& file) {
    if (meta) detail::write_itk_image_2d(image, spacing_mm, origin_mm, itk::MetaImageIO::New(), file);
    else detail::write_itk_image_2d(image, spacing_mm, origin_mm, itk::NrrdImageIO::New(), file);
  });
}

}  // namespace fluoro
