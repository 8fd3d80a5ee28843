#include "engine/image_io.hpp"

#include <itkGDCMImageIO.h>
#include <itkImage.h>
#include <itkImageFileReader.h>
#include <itkImageFileWriter.h>
#include <itkNiftiImageIO.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "engine/atomic_file.hpp"
#include "engine/error.hpp"
#include "engine/file_names.hpp"
#include "engine/volume_io.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

bool is_nifti_name(const std::string& name) {
  return ends_with(name, ".nii") || ends_with(name, ".nii.gz");
}

// Extensions OpenCV decodes; a file with none of these may still be DICOM (DICOM files often have
// no extension at all), which GDCM is asked about before falling back to OpenCV.
bool is_opencv_name(const std::string& name) {
  static const char* const exts[] = {".png", ".tif", ".tiff", ".jpg", ".jpeg", ".jpe", ".bmp",
                                     ".dib", ".pgm", ".ppm",  ".pnm", ".pbm",  ".pxm", ".exr",
                                     ".hdr", ".pic", ".webp", ".jp2", ".sr",   ".ras"};
  return std::any_of(std::begin(exts), std::end(exts),
                     [&](const char* e) { return ends_with(name, e); });
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

// ---- ITK (DICOM, NIfTI) ------------------------------------------------------------------

Image read_itk_image(const std::string& path, itk::ImageIOBase* io, bool dicom) {
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
  using ItkImage = itk::Image<float, 2>;
  auto itk_image = ItkImage::New();
  ItkImage::SizeType size;
  size[0] = itk::SizeValueType(image.width);
  size[1] = itk::SizeValueType(image.height);
  itk_image->SetRegions(ItkImage::RegionType(size));
  itk_image->GetPixelContainer()->SetImportPointer(const_cast<float*>(image.pixels.data()),
                                                   image.pixels.size(), false);
  auto writer = itk::ImageFileWriter<ItkImage>::New();
  writer->SetImageIO(itk::NiftiImageIO::New());
  writer->SetFileName(file);
  writer->SetInput(itk_image);
  try {
    writer->Update();
  } catch (const itk::ExceptionObject&) {
    throw std::runtime_error(file + ": cannot write NIfTI image");
  }
}

// ---- OpenCV --------------------------------------------------------------------------------

Image read_opencv_image(const std::string& path) {
  cv::Mat mat;
  try {
    mat = cv::imread(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR);
  } catch (const cv::Exception&) {
    mat.release();
  }
  if (mat.empty()) throw_input_error(path, "cannot read image (unknown format, corrupt or empty)");
  // Convert the depth first (cvtColor takes only 8U/16U/32F) and without scaling, so 8/16-bit
  // values stay the integers stored in the file.
  cv::Mat f;
  mat.convertTo(f, CV_32F);
  cv::Mat grey;
  switch (f.channels()) {
    case 1: grey = f; break;
    case 2: cv::extractChannel(f, grey, 0); break;  // grey + alpha
    case 3: cv::cvtColor(f, grey, cv::COLOR_BGR2GRAY); break;
    case 4: cv::cvtColor(f, grey, cv::COLOR_BGRA2GRAY); break;
    default: throw_input_error(path, "has " + std::to_string(f.channels()) + " channels per pixel");
  }
  Image image(grey.cols, grey.rows);
  for (int v = 0; v < grey.rows; ++v)
    std::copy_n(grey.ptr<float>(v), grey.cols, &image.pixels[size_t(v) * size_t(grey.cols)]);
  return image;
}

void imwrite_checked(const std::string& file, const cv::Mat& mat) {
  bool ok = false;
  try {
    ok = cv::imwrite(file, mat);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok) throw std::runtime_error(file + ": cannot write image");
}

// Encoding in memory makes the format PNG whatever the file is called.
void write_png_mat(const cv::Mat& mat, const std::string& path) {
  std::vector<uchar> encoded;
  if (!cv::imencode(".png", mat, encoded)) throw std::runtime_error(path + ": cannot encode PNG");
  write_file_atomic(path, [&](const std::string& file) {
    write_bytes(file, reinterpret_cast<const char*>(encoded.data()), encoded.size());
  });
}

void check_buffer(const Image& image, const char* who) {
  if (image.width <= 0 || image.height <= 0 ||
      image.pixels.size() != size_t(image.width) * size_t(image.height))
    throw std::invalid_argument(std::string(who) + ": pixel buffer does not match the image size");
}

}  // namespace

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
  } else if (is_nifti_name(name)) {
    detail::check_nifti_complete(path);
    image = read_itk_image(path, itk::NiftiImageIO::New(), false);
  } else if (is_opencv_name(name)) {
    image = read_opencv_image(path);
  } else {
    auto dicom = itk::GDCMImageIO::New();
    if (ends_with(name, ".dcm") || dicom->CanReadFile(path.c_str()))
      image = read_itk_image(path, dicom, true);
    else
      image = read_opencv_image(path);
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
    const cv::Mat mat(image.height, image.width, CV_32F, const_cast<float*>(image.pixels.data()));
    write_file_atomic(path, [&](const std::string& file) { imwrite_checked(file, mat); });
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
  cv::Mat mat(image.height, image.width, CV_8U);
  for (int v = 0; v < image.height; ++v) {
    uchar* row = mat.ptr<uchar>(v);
    for (int u = 0; u < image.width; ++u) {
      const float x = (image.at(u, v) - lo) * scale;
      row[u] = std::isfinite(x) ? uchar(std::lround(std::clamp(x, 0.0f, 255.0f))) : 0;
    }
  }
  write_png_mat(mat, path);
}

void write_png_u8(const std::vector<uint8_t>& pixels, int width, int height, int channels,
                  const std::string& path) {
  if (width <= 0 || height <= 0 || (channels != 1 && channels != 3) ||
      pixels.size() != size_t(width) * size_t(height) * size_t(channels))
    throw std::invalid_argument(
        "write_png_u8: pixel buffer does not match width x height x channels");
  const cv::Mat wrapped(height, width, channels == 1 ? CV_8UC1 : CV_8UC3,
                        const_cast<uint8_t*>(pixels.data()));
  if (channels == 1) {
    write_png_mat(wrapped, path);
  } else {
    cv::Mat bgr;  // OpenCV encodes BGR order
    cv::cvtColor(wrapped, bgr, cv::COLOR_RGB2BGR);
    write_png_mat(bgr, path);
  }
}

void write_png_u16(const std::vector<uint16_t>& pixels, int width, int height,
                   const std::string& path) {
  if (width <= 0 || height <= 0 || pixels.size() != size_t(width) * size_t(height))
    throw std::invalid_argument("write_png_u16: pixel buffer does not match width x height");
  write_png_mat(cv::Mat(height, width, CV_16UC1, const_cast<uint16_t*>(pixels.data())), path);
}

bool is_float_image_path(const std::string& path) {
  const std::string name = lower_file_name(path);
  return ends_with(name, ".tif") || ends_with(name, ".tiff") || ends_with(name, ".pfm") ||
         is_nifti_name(name);
}

}  // namespace fluoro
