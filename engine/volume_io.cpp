#include "engine/volume_io.hpp"

#include <itkGDCMImageIO.h>
#include <itkGDCMSeriesFileNames.h>
#include <itkImage.h>
#include <itkImageFileReader.h>
#include <itkImageFileWriter.h>
#include <itkImageIOFactory.h>
#include <itkImageSeriesReader.h>
#include <itkMetaImageIO.h>
#include <itkNiftiImageIO.h>
#include <itkNrrdImageIO.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "engine/atomic_file.hpp"
#include "engine/error.hpp"
#include "engine/file_names.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;
using ItkVolume = itk::Image<float, 3>;

// The factory only knows the formats registered for this binary (ITK_USE_FILE's generated
// register manager); asking the IOs we link directly keeps reading working without it.
itk::ImageIOBase::Pointer create_reader_io(const std::string& path) {
  itk::ImageIOBase::Pointer io =
      itk::ImageIOFactory::CreateImageIO(path.c_str(), itk::ImageIOFactory::ReadMode);
  if (io) return io;
  const itk::ImageIOBase::Pointer candidates[] = {itk::NiftiImageIO::New(), itk::MetaImageIO::New(),
                                                  itk::NrrdImageIO::New(), itk::GDCMImageIO::New()};
  for (const auto& candidate : candidates)
    if (candidate->CanReadFile(path.c_str())) return candidate;
  return nullptr;
}

// Checks what the header promises before any voxel is read, so a 2D, vector or zero-spacing file
// gets a message about that rather than whatever ITK's reader makes of it (ITK throws its own
// multi-line error on zero spacing).
void check_header(itk::ImageIOBase& io, const std::string& path) {
  const unsigned dims = io.GetNumberOfDimensions();
  if (dims != 3)
    throw_input_error(path, "is a " + std::to_string(dims) + "D image, expected a 3D volume");
  if (io.GetNumberOfComponents() != 1)
    throw_input_error(path, "has " + std::to_string(io.GetNumberOfComponents()) +
                                " components per voxel, expected a scalar volume");
  for (unsigned a = 0; a < 3; ++a) {
    if (io.GetDimensions(a) == 0) throw_input_error(path, "empty volume (a dimension is 0)");
    const double s = io.GetSpacing(a);
    if (!std::isfinite(s) || s <= 0) {
      std::ostringstream text;
      text << "spacing along axis " << a << " is " << s << " mm (must be positive)";
      throw_input_error(path, text.str());
    }
  }
}

// ---- truncation ----------------------------------------------------------------------------
// ITK 5.2 reads a short NIfTI (plain or gzipped) or MetaImage without an error (MetaIO only
// prints to stderr) and hands back garbage for the missing voxels, so for these formats the bytes
// present are compared with what the header describes before reading. NRRD and DICOM readers
// detect truncation themselves.

[[noreturn]] void throw_truncated(const std::string& path, uint64_t have, uint64_t need) {
  throw_input_error(path, "file truncated (" + std::to_string(have) + " of the " +
                              std::to_string(need) + " bytes its header describes are present)");
}

template <class T>
T read_raw(const unsigned char* p, bool swap) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swap) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

std::string trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return {};
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

// MetaImage: a text header ending with "ElementDataFile = LOCAL" (data follows in the same file)
// or naming a data file; compressed data states its size in CompressedDataSize.
void check_metaimage_complete(const std::string& path, uint64_t raw_bytes) {
  std::ifstream in(path, std::ios::binary);
  std::string line, data_file;
  uint64_t offset = 0;
  bool compressed = false;
  std::optional<uint64_t> compressed_size;
  int64_t header_size = 0;
  while (std::getline(in, line) && offset < (1u << 20)) {
    offset += line.size() + 1;
    const size_t eq = line.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = trim(line.substr(0, eq)), value = trim(line.substr(eq + 1));
    try {
      if (key == "CompressedData") compressed = to_lower(value) == "true";
      if (key == "CompressedDataSize") compressed_size = std::stoull(value);
      if (key == "HeaderSize") header_size = std::stoll(value);
    } catch (const std::exception&) {
      return;  // a malformed number is MetaIO's to report
    }
    if (key == "ElementDataFile") {
      data_file = value;
      break;
    }
  }
  if (data_file.empty() || header_size < 0) return;  // HeaderSize -1: data at the end of the file
  uint64_t need = compressed ? compressed_size.value_or(0) : raw_bytes;
  if (need == 0) return;
  std::error_code ec;
  uint64_t have = 0;
  if (to_lower(data_file) == "local") {
    const uint64_t size = fs::file_size(path, ec);
    have = size > offset ? size - offset : 0;
  } else {
    // "LIST" and printf-style patterns spread the data over several files; not checked.
    if (data_file.rfind("LIST", 0) == 0 || data_file.find('%') != std::string::npos ||
        data_file.find(' ') != std::string::npos)
      return;
    fs::path data = data_file;
    if (data.is_relative()) data = fs::path(path).parent_path() / data;
    if (!fs::exists(data, ec)) throw_input_error(path, "data file " + data.string() + " not found");
    have = fs::file_size(data, ec);
    need += uint64_t(header_size);
  }
  if (have < need) throw_truncated(path, have, need);
}

Volume from_itk(const ItkVolume& image) {
  Volume v;
  const auto size = image.GetLargestPossibleRegion().GetSize();
  for (int a = 0; a < 3; ++a) {
    v.geometry.size[a] = int(size[a]);
    v.geometry.origin[a] = image.GetOrigin()[a];
    v.geometry.spacing[a] = image.GetSpacing()[a];
    for (int b = 0; b < 3; ++b) v.geometry.direction(a, b) = image.GetDirection()(a, b);
  }
  const float* buffer = image.GetBufferPointer();
  v.voxels.assign(buffer, buffer + v.geometry.voxel_count());
  return v;
}

Volume read_file_volume(const std::string& path) {
  itk::ImageIOBase::Pointer io = create_reader_io(path);
  if (!io) throw_input_error(path, "unknown or unreadable volume format");
  io->SetFileName(path);
  try {
    io->ReadImageInformation();
  } catch (const itk::ExceptionObject&) {
    throw_input_error(path, "cannot read volume header (unreadable or corrupt file)");
  }
  check_header(*io, path);
  if (dynamic_cast<itk::NiftiImageIO*>(io.GetPointer()))
    detail::check_nifti_complete(path);
  else if (dynamic_cast<itk::MetaImageIO*>(io.GetPointer()))
    check_metaimage_complete(path, io->GetImageSizeInBytes());

  auto reader = itk::ImageFileReader<ItkVolume>::New();
  reader->SetFileName(path);
  reader->SetImageIO(io);
  try {
    reader->Update();
  } catch (const itk::ExceptionObject&) {
    // ITK's description is a multi-line dump naming its own source files; the user needs the file.
    throw_input_error(path, "cannot read volume (file truncated or corrupt)");
  }
  return from_itk(*reader->GetOutput());
}

// A directory may hold several series (or one split by GDCM's series details); the one with the
// most slices is taken, as the CT is by far the largest series in a typical export.
Volume read_dicom_series(const std::string& path) {
  std::vector<std::string> files;
  // The scan warns on stderr about every directory without a series; the InputError below says
  // it in one line instead.
  const bool warnings = itk::Object::GetGlobalWarningDisplay();
  itk::Object::SetGlobalWarningDisplay(false);
  try {
    auto names = itk::GDCMSeriesFileNames::New();
    names->SetUseSeriesDetails(true);
    names->SetDirectory(path);
    for (const std::string& uid : names->GetSeriesUIDs()) {
      std::vector<std::string> series = names->GetFileNames(uid);
      if (series.size() > files.size()) files = std::move(series);
    }
  } catch (const itk::ExceptionObject&) {
    itk::Object::SetGlobalWarningDisplay(warnings);
    throw_input_error(path, "cannot scan directory for DICOM series");
  }
  itk::Object::SetGlobalWarningDisplay(warnings);
  if (files.empty()) throw_input_error(path, "directory holds no DICOM series");

  auto io = itk::GDCMImageIO::New();
  io->SetFileName(files.front());
  try {
    io->ReadImageInformation();
  } catch (const itk::ExceptionObject&) {
    throw_input_error(path, "cannot read DICOM header of " + files.front());
  }
  if (io->GetNumberOfComponents() != 1)
    throw_input_error(path, "DICOM series has " + std::to_string(io->GetNumberOfComponents()) +
                                " components per pixel, expected a scalar volume");
  if (io->GetNumberOfDimensions() >= 3 && io->GetDimensions(2) > 1)
    throw_input_error(path, "multi-frame DICOM series not supported");

  auto reader = itk::ImageSeriesReader<ItkVolume>::New();
  reader->SetImageIO(io);
  reader->SetFileNames(files);
  try {
    reader->Update();
  } catch (const itk::ExceptionObject&) {
    throw_input_error(path, "cannot read DICOM series (truncated, corrupt or inconsistent slices)");
  }
  return from_itk(*reader->GetOutput());
}

}  // namespace

// Reads the header itself (not ITK's view of it: ITK reports rescaled integer data as float, which
// would overstate the stored size). zlib reads an uncompressed .nii transparently.
void detail::check_nifti_complete(const std::string& path) {
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) return;  // ITK has already read the header, so this cannot really happen
  struct Closer {
    gzFile f;
    ~Closer() { gzclose(f); }
  } closer{f};
  unsigned char hdr[540] = {};
  const int got = gzread(f, hdr, sizeof hdr);
  if (got < 348) throw_truncated(path, uint64_t(std::max(got, 0)), 348);
  int32_t sizeof_hdr = read_raw<int32_t>(hdr, false);
  bool swap = false;
  if (sizeof_hdr != 348 && sizeof_hdr != 540) {
    swap = true;
    sizeof_hdr = read_raw<int32_t>(hdr, true);
  }
  uint64_t voxels = 1, vox_offset = 0;
  int bitpix = 0;
  if (sizeof_hdr == 348) {
    if (std::memcmp(hdr + 344, "n+1", 4) != 0) return;  // a .hdr/.img pair: data lives elsewhere
    const int ndim = read_raw<int16_t>(hdr + 40, swap);
    if (ndim < 1 || ndim > 7) return;
    for (int d = 1; d <= ndim; ++d)
      voxels *= uint64_t(std::max<int16_t>(read_raw<int16_t>(hdr + 40 + 2 * d, swap), 1));
    bitpix = read_raw<int16_t>(hdr + 72, swap);
    vox_offset = uint64_t(std::max(read_raw<float>(hdr + 108, swap), 352.0f));
  } else if (sizeof_hdr == 540 && got == 540) {
    if (std::memcmp(hdr + 4, "n+2", 4) != 0) return;
    const int64_t ndim = read_raw<int64_t>(hdr + 16, swap);
    if (ndim < 1 || ndim > 7) return;
    for (int d = 1; d <= ndim; ++d)
      voxels *= uint64_t(std::max<int64_t>(read_raw<int64_t>(hdr + 16 + 8 * d, swap), 1));
    bitpix = read_raw<int16_t>(hdr + 14, swap);
    vox_offset = uint64_t(std::max<int64_t>(read_raw<int64_t>(hdr + 168, swap), 544));
  } else {
    return;  // not a header we know; leave it to ITK
  }
  if (bitpix <= 0) return;
  const uint64_t need = vox_offset + voxels * uint64_t(bitpix) / 8;
  uint64_t have = uint64_t(got);
  if (gzdirect(f)) {
    std::error_code ec;
    have = fs::file_size(path, ec);
  } else {
    // A gzip stream's size is only known by inflating it; stop as soon as enough has arrived.
    std::vector<char> chunk(1 << 20);
    while (have < need) {
      const int n = gzread(f, chunk.data(), unsigned(chunk.size()));
      if (n <= 0) break;
      have += uint64_t(n);
    }
  }
  if (have < need) throw_truncated(path, have, need);
}

Volume read_volume(const std::string& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!fs::exists(status)) throw_input_error(path, "file not found");
  Volume v = fs::is_directory(status) ? read_dicom_series(path) : read_file_volume(path);
  validate_volume(v, path);
  return v;
}

void write_volume(const Volume& volume, const std::string& path) {
  const std::string name = lower_file_name(path);
  const bool mhd = ends_with(name, ".mhd");
  const bool compress = ends_with(name, ".mha") || ends_with(name, ".nrrd");
  if (!(ends_with(name, ".nii") || ends_with(name, ".nii.gz") || ends_with(name, ".mha") || mhd ||
        ends_with(name, ".nrrd")))
    throw_input_error(path,
                      "unsupported volume extension (use .nii, .nii.gz, .mha, .mhd or .nrrd)");
  const VolumeGeometry& g = volume.geometry;
  if ((g.size.array() <= 0).any() || volume.voxels.size() != g.voxel_count())
    throw std::invalid_argument("write_volume: voxel buffer does not match the geometry");

  auto image = ItkVolume::New();
  ItkVolume::SizeType size;
  ItkVolume::PointType origin;
  ItkVolume::SpacingType spacing;
  ItkVolume::DirectionType direction;
  for (int a = 0; a < 3; ++a) {
    size[a] = itk::SizeValueType(g.size[a]);
    origin[a] = g.origin[a];
    spacing[a] = g.spacing[a];
    for (int b = 0; b < 3; ++b) direction(a, b) = g.direction(a, b);
  }
  image->SetRegions(ItkVolume::RegionType(size));
  image->SetOrigin(origin);
  image->SetSpacing(spacing);
  image->SetDirection(direction);
  // Borrow the voxels rather than copy a possibly multi-GB buffer; the writer only reads them.
  image->GetPixelContainer()->SetImportPointer(const_cast<float*>(volume.voxels.data()),
                                               volume.voxels.size(), false);

  const auto write = [&](const std::string& file) {
    auto writer = itk::ImageFileWriter<ItkVolume>::New();
    writer->SetFileName(file);
    writer->SetInput(image);
    // Single-file containers are compressed (CT compresses well); NIfTI follows its name (.nii.gz)
    // and .mhd stays raw so its data file is a plain .raw.
    writer->SetUseCompression(compress);
    try {
      writer->Update();
    } catch (const itk::ExceptionObject& e) {
      // The description (unlike what()) is ITK's message alone, e.g. why a file cannot be opened.
      std::string reason = e.GetDescription();
      std::replace(reason.begin(), reason.end(), '\n', ' ');
      throw std::runtime_error(path + ": cannot write volume (" + reason + ")");
    }
  };
  // A .mhd header names its companion .raw file, so writing it under a temporary name and renaming
  // would leave the header pointing at the temporary's data file; it is written in place (not
  // atomic). Every other format is a single file and goes through the atomic rename.
  if (mhd)
    write(path);
  else
    write_file_atomic(path, write);
}

}  // namespace fluoro
