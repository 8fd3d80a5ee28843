#include "engine/spaced_image_writer.hpp"

#include <itkImage.h>
#include <itkImageFileWriter.h>
#include <itkMetaImageIO.h>
#include <itkNrrdImageIO.h>

#include <stdexcept>

#include "engine/atomic_file.hpp"
#include "engine/error.hpp"
#include "engine/file_names.hpp"

namespace fluoro {

bool is_spaced_image_path(const std::string& path) {
  const std::string ext = lower_extension(path);
  return ext == ".mha" || ext == ".nrrd";
}

void write_spaced_image(const Image& image, const Eigen::Vector2d& spacing_mm, const Eigen::Vector2d& origin_mm,
                        const std::string& path) {
  if (!is_spaced_image_path(path)) throw_input_error(path, "unsupported extension (use .mha or .nrrd)");
  if (image.width <= 0 || image.height <= 0 || image.pixels.size() != size_t(image.width) * size_t(image.height))
    throw std::invalid_argument("write_spaced_image: pixel buffer does not match width x height");
  if (!(spacing_mm.array() > 0).all() || !spacing_mm.allFinite() || !origin_mm.allFinite())
    throw std::invalid_argument("write_spaced_image: spacing must be positive, the origin finite");
  using ItkImage = itk::Image<float, 2>;
  auto itk_image = ItkImage::New();
  ItkImage::SizeType size;
  size[0] = itk::SizeValueType(image.width);
  size[1] = itk::SizeValueType(image.height);
  itk_image->SetRegions(ItkImage::RegionType(size));
  const double spacing[2] = {spacing_mm.x(), spacing_mm.y()};
  itk_image->SetSpacing(spacing);
  const double origin[2] = {origin_mm.x(), origin_mm.y()};
  itk_image->SetOrigin(origin);
  // Not copied: the writer only reads the buffer.
  itk_image->GetPixelContainer()->SetImportPointer(const_cast<float*>(image.pixels.data()), image.pixels.size(), false);
  const bool meta = lower_extension(path) == ".mha";
  write_file_atomic(path, [&](const std::string& file) {
    auto writer = itk::ImageFileWriter<ItkImage>::New();
    // The IO chosen here, not by ITK's factories: the extension is already checked.
    if (meta) writer->SetImageIO(itk::MetaImageIO::New());
    else writer->SetImageIO(itk::NrrdImageIO::New());
    writer->SetFileName(file);
    writer->SetInput(itk_image);
    try {
      writer->Update();
    } catch (const itk::ExceptionObject& e) {
      throw std::runtime_error(std::string("ITK image writer: ") + e.GetDescription());
    }
  });
}

}  // namespace fluoro
