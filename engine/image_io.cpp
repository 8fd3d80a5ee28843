#include "engine/image_io.hpp"

#include <itkBMPImageIO.h>
#include <itkImage.h>
#include <itkImageFileReader.h>
#include <itkImageFileWriter.h>
#include <itkJPEGImageIO.h>
#include <itkNiftiImageIO.h>
#include <itkPNGImageIO.h>
#include <itkTIFFImageIO.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <opencv2/core.hpp>
#include <stdexcept>
#include <string_view>

#include "engine/atomic_file.hpp"
#include "engine/dicom_file_check.hpp"
#include "engine/dicom_library.hpp"
#include "engine/error.hpp"
#include "engine/file_names.hpp"
#include "engine/isolated_read.hpp"
#include "engine/itk_image_2d_writer.hpp"
#include "engine/library_output.hpp"
#include "engine/png_reader.hpp"
#include "engine/tiff_tags.hpp"
#include "engine/png_writer.hpp"
#include "engine/volume_io.hpp"
#include "engine/widen_to_float.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

bool is_nifti_name(const std::string& name) {
  return ends_with(name, ".nii") || ends_with(name, ".nii.gz");
}

std::vector<char> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_input_error(path, "cannot open file");
  return std::vector<char>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void write_bytes(const std::string& file, const char* data, size_t size) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(data, std::streamsize(size));
  out.close();
  if (!out) throw std::runtime_error(file + ": cannot write file");
}

// ---- PFM -----------------------------------------------------------------------------------
// Portable float map: "Pf" (grey) or "PF" (RGB), width, height, then a scale whose sign gives the
// byte order (negative: little-endian), one whitespace byte, and rows stored bottom to top.

float byte_swapped(float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  u = (u >> 24) | ((u >> 8) & 0xff00u) | ((u << 8) & 0xff0000u) | (u << 24);
  std::memcpy(&f, &u, 4);
  return f;
}

Image read_pfm(const std::string& path) {
  const std::vector<char> bytes = read_bytes(path);
  size_t pos = 0;
  const auto token = [&]() {
    while (pos < bytes.size() && std::isspace(static_cast<unsigned char>(bytes[pos]))) ++pos;
    const size_t start = pos;
    while (pos < bytes.size() && !std::isspace(static_cast<unsigned char>(bytes[pos]))) ++pos;
    return std::string(bytes.data() + start, pos - start);
  };
  const std::string magic = token();
  if (magic != "Pf" && magic != "PF") throw_input_error(path, "not a PFM file (bad magic)");
  const int channels = magic == "PF" ? 3 : 1;
  long width = 0, height = 0;
  double scale = 0;
  try {
    width = std::stol(token());
    height = std::stol(token());
    scale = std::stod(token());
  } catch (const std::exception&) {
    throw_input_error(path, "corrupt PFM header");
  }
  if (width <= 0 || height <= 0 || width > (1 << 20) || height > (1 << 20) || scale == 0 ||
      !std::isfinite(scale))
    throw_input_error(path, "corrupt PFM header");
  ++pos;  // the single whitespace byte that ends the header
  const size_t count = size_t(width) * size_t(height) * size_t(channels);
  if (pos > bytes.size() || bytes.size() - pos < count * sizeof(float))
    throw_input_error(path, "file truncated (PFM data shorter than its header says)");
  const bool swap = (scale < 0) != (std::endian::native == std::endian::little);

  Image image{int(width), int(height)};
  const char* data = bytes.data() + pos;
  for (int row = 0; row < image.height; ++row) {
    const int v = image.height - 1 - row;  // file rows run bottom to top
    for (int u = 0; u < image.width; ++u) {
      float c[3];
      std::memcpy(c, data + (size_t(row) * size_t(width) + size_t(u)) * size_t(channels) * 4,
                  size_t(channels) * 4);
      if (swap)
        for (int k = 0; k < channels; ++k) c[k] = byte_swapped(c[k]);
      image.at(u, v) = channels == 1 ? c[0] : 0.299f * c[0] + 0.587f * c[1] + 0.114f * c[2];
    }
  }
  return image;
}

void write_pfm(const Image& image, const std::string& file) {
  const std::string header = "Pf\n" + std::to_string(image.width) + " " +
                             std::to_string(image.height) + "\n" +
                             (std::endian::native == std::endian::little ? "-1.0\n" : "1.0\n");
  std::vector<char> bytes(header.begin(), header.end());
  bytes.resize(header.size() + image.pixels.size() * sizeof(float));
  char* data = bytes.data() + header.size();
  const size_t row_bytes = size_t(image.width) * sizeof(float);
  for (int row = 0; row < image.height; ++row)
    std::memcpy(data + size_t(row) * row_bytes,
                &image.pixels[size_t(image.height - 1 - row) * size_t(image.width)], row_bytes);
  write_bytes(file, bytes.data(), bytes.size());
}

// ---- ITK (DICOM; NIfTI is written here) -------------------------------------------------

Image read_itk_image(const std::string& path, itk::ImageIOBase* io, bool dicom) {
  CapturedLibraryOutput library;  // what ITK's readers print is not for the user (library_output.hpp)
  io->SetFileName(path);
  try {
    io->ReadImageInformation();
  } catch (const itk::ExceptionObject&) {
    throw_input_error(path, dicom ? "cannot read DICOM header (unreadable or corrupt file)"
                                  : "cannot read image header (unreadable or corrupt file)");
  }
  const unsigned dims = io->GetNumberOfDimensions();
  if (dims < 2 || dims > 3)
    throw_input_error(path, "is a " + std::to_string(dims) + "D image, expected a 2D image");
  if (dims == 3 && io->GetDimensions(2) > 1)
    throw_input_error(path, dicom ? "multi-frame DICOM not supported"
                                  : "is a 3D volume with " + std::to_string(io->GetDimensions(2)) +
                                        " slices, expected a 2D image");
  const unsigned components = io->GetNumberOfComponents();
  if (components != 1 && components != 3 && components != 4)
    throw_input_error(path, "has " + std::to_string(components) + " components per pixel");

  // Read as 3D so 2D files and single-slice 3D files take the same path; ITK converts RGB(A) to
  // luminance for the scalar output.
  using ItkImage = itk::Image<float, 3>;
  auto reader = itk::ImageFileReader<ItkImage>::New();
  reader->SetFileName(path);
  reader->SetImageIO(io);
  try {
    reader->Update();
  } catch (const itk::ExceptionObject&) {
    throw_input_error(path, "cannot read image (file truncated or corrupt)");
  }
  const ItkImage* out = reader->GetOutput();
  const auto size = out->GetLargestPossibleRegion().GetSize();
  if (size[2] != 1) throw_input_error(path, "multi-frame image not supported");
  Image image{int(size[0]), int(size[1])};
  // ITK index j runs down the rows as stored, the first stored row being the top one (DICOM).
  std::copy_n(out->GetBufferPointer(), image.pixels.size(), image.pixels.begin());
  return image;
}

void write_nifti_image(const Image& image, const std::string& file) {
  detail::write_itk_image_2d(image, Eigen::Vector2d::Ones(), Eigen::Vector2d::Zero(), itk::NiftiImageIO::New(), file);
}

// ---- PNG, TIFF, JPEG, BMP through ITK's image IO ---------------------------------------------
// Not OpenCV's imgcodecs: Debian builds it against GDAL, whose ~130 shared libraries every run of
// the program would load and bind before doing any work (half of its start-up time).

itk::ImageIOBase::Pointer raster_io_for(const std::string& name) {
  if (ends_with(name, ".png")) return itk::PNGImageIO::New().GetPointer();
  if (ends_with(name, ".tif") || ends_with(name, ".tiff")) return itk::TIFFImageIO::New().GetPointer();
  if (ends_with(name, ".jpg") || ends_with(name, ".jpeg") || ends_with(name, ".jpe"))
    return itk::JPEGImageIO::New().GetPointer();
  if (ends_with(name, ".bmp") || ends_with(name, ".dib")) return itk::BMPImageIO::New().GetPointer();
  return nullptr;
}

// The stored type of an ITK component type that images hold (no 64-bit integers).
std::optional<StoredType> image_stored_type(itk::IOComponentEnum type) {
  using C = itk::IOComponentEnum;
  switch (type) {
    case C::UCHAR: return StoredType::u8;
    case C::CHAR: return StoredType::i8;
    case C::USHORT: return StoredType::u16;
    case C::SHORT: return StoredType::i16;
    case C::UINT: return StoredType::u32;
    case C::INT: return StoredType::i32;
    case C::FLOAT: return StoredType::f32;
    case C::DOUBLE: return StoredType::f64;
    default: return std::nullopt;
  }
}

// libpng through ITK aborts on some corrupt headers and prints its own lines: PNG goes to
// engine/png_reader.hpp. Its 16-bit samples are native-order uint16.
Image read_png_image(const std::string& path) {
  const PngPixels png = read_png_file(path);
  std::vector<float> values(size_t(png.width) * size_t(png.height) * size_t(png.channels));
  for (size_t i = 0; i < values.size(); ++i) {
    if (png.bit_depth == 8) {
      values[i] = png.bytes[i];
    } else {
      uint16_t v;
      std::memcpy(&v, &png.bytes[2 * i], 2);
      values[i] = v;
    }
  }
  Image image(png.width, png.height);
  const size_t channels = size_t(png.channels);
  for (size_t i = 0; i < image.pixels.size(); ++i) {
    const float* c = &values[i * channels];
    image.pixels[i] = channels < 3 ? c[0] : 0.299f * c[0] + 0.587f * c[1] + 0.114f * c[2];
  }
  return image;
}

Image read_raster_image(const std::string& path, itk::ImageIOBase* io) {
  if (dynamic_cast<itk::PNGImageIO*>(io)) return read_png_image(path);
  if (dynamic_cast<itk::TIFFImageIO*>(io)) check_tiff_tags(path);
  CapturedLibraryOutput library;  // libtiff's and libjpeg's messages become the InputError below
  io->SetFileName(path);
  const std::string corrupt = "cannot read image (unknown format, corrupt or empty)";
  try {
    if (!io->CanReadFile(path.c_str())) throw_input_error(path, corrupt);
    io->ReadImageInformation();
  } catch (const itk::ExceptionObject&) {
    throw_input_error(path, corrupt);
  }
  const unsigned dims = io->GetNumberOfDimensions();
  if (dims == 3 && io->GetDimensions(2) > 1)
    throw_input_error(path, "multi-frame image (" + std::to_string(io->GetDimensions(2)) +
                                " pages) not supported, expected a 2D image");
  if (dims < 2 || dims > 3) throw_input_error(path, "is a " + std::to_string(dims) + "D image");
  const unsigned channels = io->GetNumberOfComponents();
  if (channels < 1 || channels > 4)
    throw_input_error(path, "has " + std::to_string(channels) + " channels per pixel");
  const int width = int(io->GetDimensions(0)), height = int(io->GetDimensions(1));
  if (width <= 0 || height <= 0) throw_input_error(path, "empty image (0 pixels)");

  std::vector<char> bytes(io->GetImageSizeInBytes());
  try {
    io->Read(bytes.data());
  } catch (const itk::ExceptionObject&) {
    throw_input_error(path, "cannot read image (file truncated or corrupt)");
  }
  // Each component type converted without scaling (8/16-bit values stay the integers in the file).
  const std::optional<StoredType> type = image_stored_type(io->GetComponentType());
  if (!type) throw_input_error(path, "unsupported pixel component type");
  std::vector<float> values(bytes.size() / size_t(stored_type_bytes(*type)));
  widen_to_float(*type, bytes.data(), values.data(), values.size());
  const size_t count = size_t(width) * size_t(height);
  if (values.size() < count * channels) throw_input_error(path, "file truncated (fewer pixels than its header says)");
  Image image(width, height);
  for (size_t i = 0; i < count; ++i) {
    const float* c = &values[i * channels];
    // Grey (+ alpha): the grey value; RGB(A): ITU-R BT.601 luma, as OpenCV's RGB2GRAY.
    image.pixels[i] = channels < 3 ? c[0] : 0.299f * c[0] + 0.587f * c[1] + 0.114f * c[2];
  }
  return image;
}

// Writes a 2D buffer of `channels` interleaved components (row 0 at the top) with an ITK image IO.
void write_raster(itk::ImageIOBase* io, const void* data, int width, int height, unsigned channels,
                  itk::IOComponentEnum component, const std::string& file) {
  io->SetNumberOfDimensions(2);
  io->SetDimensions(0, unsigned(width));
  io->SetDimensions(1, unsigned(height));
  io->SetComponentType(component);
  io->SetNumberOfComponents(channels);
  io->SetPixelType(channels == 1 ? itk::IOPixelEnum::SCALAR : itk::IOPixelEnum::RGB);
  io->SetFileName(file);
  try {
    io->WriteImageInformation();
    io->Write(data);
  } catch (const itk::ExceptionObject&) {
    throw std::runtime_error(file + ": cannot write image");
  }
}

// PNG whatever the file is called, through libpng directly (engine/png_writer.hpp: the Sub
// filter and zlib level 1 with run-length matching; ITK's PNGImageIO tries all filters per row and
// costs about 2.7 times as much on a panorama).
void write_png_buffer(const void* data, int width, int height, unsigned channels,
                      itk::IOComponentEnum component, const std::string& path) {
  if (component != itk::IOComponentEnum::UCHAR && component != itk::IOComponentEnum::USHORT)
    throw std::invalid_argument("write_png_buffer: 8- or 16-bit samples");
  write_file_atomic(path, [&](const std::string& file) {
    write_png_file(data, width, height, int(channels), component == itk::IOComponentEnum::UCHAR ? 8 : 16, file);
  });
}

void check_buffer(const Image& image, const char* who) {
  if (image.width <= 0 || image.height <= 0 ||
      image.pixels.size() != size_t(image.width) * size_t(image.height))
    throw std::invalid_argument(std::string(who) + ": pixel buffer does not match the image size");
}

}  // namespace

cv::Mat read_stored_image(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw_input_error(path, "file not found");
  itk::ImageIOBase::Pointer io = raster_io_for(lower_file_name(path));
  if (!io) throw_input_error(path, "not a PNG, TIFF, JPEG or BMP file (by its extension)");
  if (dynamic_cast<itk::PNGImageIO*>(io.GetPointer())) {
    PngPixels png = read_png_file(path);
    cv::Mat image(png.height, png.width, CV_MAKETYPE(png.bit_depth == 8 ? CV_8U : CV_16U, png.channels));
    std::memcpy(image.data, png.bytes.data(), png.bytes.size());
    return image;
  }
  if (dynamic_cast<itk::TIFFImageIO*>(io.GetPointer())) check_tiff_tags(path);
  CapturedLibraryOutput library;
  io->SetFileName(path);
  try {
    if (!io->CanReadFile(path.c_str())) throw_input_error(path, "cannot read image (unknown format, corrupt or empty)");
    io->ReadImageInformation();
  } catch (const itk::ExceptionObject&) {
    throw_input_error(path, "cannot read image (unknown format, corrupt or empty)");
  }
  if (io->GetNumberOfDimensions() == 3 && io->GetDimensions(2) > 1)
    throw_input_error(path, "multi-frame image not supported, expected a 2D image");
  const int channels = int(io->GetNumberOfComponents());
  int depth = -1;
  using C = itk::IOComponentEnum;
  switch (io->GetComponentType()) {
    case C::UCHAR: depth = CV_8U; break;
    case C::CHAR: depth = CV_8S; break;
    case C::USHORT: depth = CV_16U; break;
    case C::SHORT: depth = CV_16S; break;
    case C::INT: depth = CV_32S; break;
    case C::FLOAT: depth = CV_32F; break;
    case C::DOUBLE: depth = CV_64F; break;
    default: throw_input_error(path, "unsupported pixel component type");
  }
  if (channels < 1 || channels > 4) throw_input_error(path, "has " + std::to_string(channels) + " channels per pixel");
  cv::Mat image(int(io->GetDimensions(1)), int(io->GetDimensions(0)), CV_MAKETYPE(depth, channels));
  if (image.empty() || size_t(io->GetImageSizeInBytes()) != image.total() * image.elemSize())
    throw_input_error(path, "cannot read image (unexpected layout)");
  try {
    io->Read(image.data);
  } catch (const itk::ExceptionObject&) {
    throw_input_error(path, "cannot read image (file truncated or corrupt)");
  }
  return image;
}

void write_stored_image(const cv::Mat& image, const std::string& path) {
  const std::string name = lower_file_name(path);
  itk::ImageIOBase::Pointer io = raster_io_for(name);
  const bool png = ends_with(name, ".png"), tiff = ends_with(name, ".tif") || ends_with(name, ".tiff");
  const int depth = image.depth();
  const bool ok = io && (depth == CV_8U || (depth == CV_16U && (png || tiff)) || (depth == CV_32F && tiff));
  if (!ok)
    throw_input_error(path, "this format cannot hold the image's bit depth (8-bit: .png, .tif, .jpg, .bmp; "
                            "16-bit: .png, .tif; float: .tif)");
  if (image.empty() || image.channels() > 4 || !image.isContinuous())
    throw std::invalid_argument("write_stored_image: expected a continuous image of 1-4 channels");
  const auto component = depth == CV_8U    ? itk::IOComponentEnum::UCHAR
                         : depth == CV_16U ? itk::IOComponentEnum::USHORT
                                           : itk::IOComponentEnum::FLOAT;
  if (png) {
    write_png_buffer(image.data, image.cols, image.rows, unsigned(image.channels()), component, path);
    return;
  }
  write_file_atomic(path, [&](const std::string& file) {
    itk::ImageIOBase::Pointer fresh = raster_io_for(name);
    write_raster(fresh, image.data, image.cols, image.rows, unsigned(image.channels()), component, file);
  });
}

Image read_image(const std::string& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!fs::exists(status)) throw_input_error(path, "file not found");
  if (fs::is_directory(status)) throw_input_error(path, "is a directory, expected an image file");
  if (fs::file_size(path, ec) == 0) throw_input_error(path, "empty file (0 bytes)");

  const std::string name = lower_file_name(path);
  Image image;
  if (ends_with(name, ".pfm")) {
    image = read_pfm(path);
  } else if (is_volume_file_name(name)) {
    // The volume reader's checks and readers, which a fuzzed NIfTI, MetaImage or NRRD file needs
    // (engine/nifti_header.hpp, engine/metaimage_header.hpp, engine/nrrd_header.hpp): a 2D file,
    // or a 3D one a slice thick; pixel (u, v) is index (u, v, 0).
    const Volume planar = read_planar_volume(path);
    image = Image(planar.geometry.size.x(), planar.geometry.size.y());
    std::copy(planar.voxels.begin(), planar.voxels.end(), image.pixels.begin());
  } else if (itk::ImageIOBase::Pointer raster = raster_io_for(name)) {
    image = read_raster_image(path, raster);
  } else {
    // DICOM files often have no extension at all: a DICOM Part 10 file (the DICM magic) is read
    // by GDCM, after the check of its element lengths that keeps GDCM from allocating what a
    // corrupt length states (engine/dicom_file_check.hpp); other files by their contents.
    // GDCM may still abort the process on a malformed file: it reads in a child process
    // (engine/isolated_read.hpp), which hands back the width, the height and the pixels.
    if (ends_with(name, ".dcm") || has_dicom_magic(path)) {
      check_dicom_file(path);
      const DicomLibrary& dicom = dicom_library();  // loaded here, not in the child
      const auto produce = [&](const IsolatedWrite& write) {
        const Image read = read_itk_image(path, dicom.new_image_io(), true);
        const int32_t size[2] = {read.width, read.height};
        write(size, sizeof size);
        write(read.pixels.data(), read.pixels.size() * sizeof(float));
      };
      const auto consume = [&](std::string_view bytes) {
        int32_t size[2] = {0, 0};
        if (bytes.size() >= sizeof size) std::memcpy(size, bytes.data(), sizeof size);
        if (bytes.size() < sizeof size || size[0] < 0 || size[1] < 0 ||
            bytes.size() - sizeof size != size_t(size[0]) * size_t(size[1]) * sizeof(float))
          throw std::runtime_error("read_image: a child's answer does not hold the pixels its size describes");
        image = Image(size[0], size[1]);
        std::memcpy(image.pixels.data(), bytes.data() + sizeof size, image.pixels.size() * sizeof(float));
      };
      run_isolated_read(path, "GDCM (the DICOM library)", produce, consume);
    } else {
      itk::ImageIOBase::Pointer by_content;
      for (const char* ext : {".png", ".tif", ".jpg", ".bmp"}) {
        itk::ImageIOBase::Pointer io = raster_io_for(ext);
        if (io->CanReadFile(path.c_str())) {
          by_content = io;
          break;
        }
      }
      if (!by_content)
        throw_input_error(path,
                          "unknown image format (expected PNG, TIFF, JPEG, BMP, DICOM, PFM, NIfTI, MetaImage or NRRD)");
      image = read_raster_image(path, by_content);
    }
  }
  if (image.empty()) throw_input_error(path, "empty image (0 pixels)");
  for (int v = 0; v < image.height; ++v)
    for (int u = 0; u < image.width; ++u)
      if (!std::isfinite(image.at(u, v)))
        throw_input_error(path, "non-finite pixel value (NaN or inf) at (" + std::to_string(u) +
                                    ", " + std::to_string(v) + ")");
  return image;
}

void write_float_image(const Image& image, const std::string& path) {
  check_buffer(image, "write_float_image");
  const std::string name = lower_file_name(path);
  if (ends_with(name, ".tif") || ends_with(name, ".tiff")) {
    write_file_atomic(path, [&](const std::string& file) {
      write_raster(itk::TIFFImageIO::New(), image.pixels.data(), image.width, image.height, 1,
                   itk::IOComponentEnum::FLOAT, file);
    });
  } else if (ends_with(name, ".pfm")) {
    write_file_atomic(path, [&](const std::string& file) { write_pfm(image, file); });
  } else if (is_nifti_name(name)) {
    write_file_atomic(path, [&](const std::string& file) { write_nifti_image(image, file); });
  } else {
    throw_input_error(path,
                      "unsupported float image extension (use .tif, .tiff, .pfm, .nii or .nii.gz)");
  }
}

void write_png(const Image& image, const std::string& path, float lo, float hi) {
  check_buffer(image, "write_png");
  // A degenerate window maps everything to black rather than dividing by zero.
  const float scale = hi != lo ? 255.0f / (hi - lo) : 0.0f;
  std::vector<uint8_t> grey(image.pixels.size());
  for (size_t i = 0; i < grey.size(); ++i) {
    const float x = (image.pixels[i] - lo) * scale;
    grey[i] = std::isfinite(x) ? uint8_t(std::lround(std::clamp(x, 0.0f, 255.0f))) : 0;
  }
  write_png_buffer(grey.data(), image.width, image.height, 1, itk::IOComponentEnum::UCHAR, path);
}

void write_png_u8(const std::vector<uint8_t>& pixels, int width, int height, int channels,
                  const std::string& path) {
  if (width <= 0 || height <= 0 || (channels != 1 && channels != 3) ||
      pixels.size() != size_t(width) * size_t(height) * size_t(channels))
    throw std::invalid_argument(
        "write_png_u8: pixel buffer does not match width x height x channels");
  write_png_buffer(pixels.data(), width, height, unsigned(channels), itk::IOComponentEnum::UCHAR, path);
}

void write_png_u16(const std::vector<uint16_t>& pixels, int width, int height,
                   const std::string& path) {
  if (width <= 0 || height <= 0 || pixels.size() != size_t(width) * size_t(height))
    throw std::invalid_argument("write_png_u16: pixel buffer does not match width x height");
  write_png_buffer(pixels.data(), width, height, 1, itk::IOComponentEnum::USHORT, path);
}

bool is_float_image_path(const std::string& path) {
  const std::string name = lower_file_name(path);
  return ends_with(name, ".tif") || ends_with(name, ".tiff") || ends_with(name, ".pfm") ||
         is_nifti_name(name);
}

}  // namespace fluoro
