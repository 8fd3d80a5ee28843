#include "engine/volume_io.hpp"

#include <itkImage.h>
#include <itkImageFileWriter.h>
#include <itkImageFileReader.h>
#include <itkImageSeriesReader.h>
#include <itkMetaImageIO.h>
#include <itkNiftiImageIO.h>
#include <itkNrrdImageIO.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <memory>
#include <new>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string_view>

#include "engine/atomic_file.hpp"
#include "engine/dicom_file_check.hpp"
#include "engine/dicom_library.hpp"
#include "engine/error.hpp"
#include "engine/file_names.hpp"
#include "engine/isolated_read.hpp"
#include "engine/library_output.hpp"
#include "engine/metaimage_header.hpp"
#include "engine/nifti_header.hpp"
#include "engine/nrrd_header.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;
using ItkVolume = itk::Image<float, 3>;

// Only the volume formats are asked, not ITK's factory: it also offers the 2D raster IOs, and a
// PNG named .nrrd then reached ITK's PNG reader, which lets libpng abort the process on a corrupt
// header (fuzz_volume_nrrd).
// A NRRD name is read as NRRD only: GDCM's probe spent 11-25 s and 1.8 GB on a fuzzed non-NRRD file
// named .nrrd (fuzz_volume_nrrd), which the NRRD check now refuses first anyway.
bool is_nrrd_name(const std::string& name) { return ends_with(name, ".nrrd") || ends_with(name, ".nhdr"); }

// The NIfTI, MetaImage or NRRD reader that takes the file, by its contents.
itk::ImageIOBase::Pointer non_dicom_io(const std::string& path) {
  const itk::ImageIOBase::Pointer candidates[] = {itk::NiftiImageIO::New(), itk::MetaImageIO::New(),
                                                  itk::NrrdImageIO::New()};
  for (const auto& candidate : candidates)
    if (candidate->CanReadFile(path.c_str())) return candidate;
  return nullptr;
}

// The reader for the file, after its format's own header check. GDCM, whose probe parses the
// file, sizes its elements by their stated lengths and aborts the process on an assertion, is
// offered a .dcm name (read as DICOM only) or a file with the DICOM magic that no other volume
// reader takes (never a NRRD name), and only when `gdcm_allowed`: in a child process, after the
// DICOM check (read_volume). Otherwise such a file sets `for_gdcm` and gets no reader.
itk::ImageIOBase::Pointer create_reader_io(const std::string& path, bool gdcm_allowed, bool& for_gdcm) {
  for_gdcm = false;
  const std::string name = lower_file_name(path);
  if (is_nrrd_name(name)) {
    itk::ImageIOBase::Pointer nrrd = itk::NrrdImageIO::New();
    return nrrd->CanReadFile(path.c_str()) ? nrrd : nullptr;
  }
  if (!ends_with(name, ".dcm")) {
    if (itk::ImageIOBase::Pointer io = non_dicom_io(path)) return io;
    if (!has_dicom_magic(path)) return nullptr;
  }
  for_gdcm = true;
  if (!gdcm_allowed) return nullptr;
  itk::ImageIOBase::Pointer gdcm = dicom_library().new_image_io();
  return gdcm->CanReadFile(path.c_str()) ? gdcm : nullptr;
}

// What a file is read as: a volume (3D), or a 2D image (2D, or 3D one slice thick) held in a
// volume format, read as a volume one voxel deep.
enum class Shape { volume, planar };

// Checks what the header promises before any voxel is read, so a file of the wrong dimensions,
// a vector or zero-spacing file gets a message about that rather than whatever ITK's reader makes
// of it (ITK throws its own multi-line error on zero spacing).
void check_header(itk::ImageIOBase& io, const std::string& path, Shape shape) {
  const unsigned dims = io.GetNumberOfDimensions();
  if (shape == Shape::volume && dims != 3)
    throw_input_error(path, "is a " + std::to_string(dims) + "D image, expected a 3D volume");
  if (shape == Shape::planar && dims != 2 && dims != 3)
    throw_input_error(path, "is a " + std::to_string(dims) + "D image, expected a 2D image");
  if (shape == Shape::planar && dims == 3 && io.GetDimensions(2) != 1)
    throw_input_error(path, "is a 3D volume with " + std::to_string(io.GetDimensions(2)) +
                                " slices, expected a 2D image");
  if (io.GetComponentType() == itk::IOComponentEnum::UNKNOWNCOMPONENTTYPE)
    throw_input_error(path, "unknown voxel component type");
  if (io.GetNumberOfComponents() != 1)
    throw_input_error(path, "has " + std::to_string(io.GetNumberOfComponents()) +
                                (shape == Shape::planar ? " components per pixel, expected a grey image"
                                                        : " components per voxel, expected a scalar volume"));
  for (unsigned a = 0; a < dims; ++a) {
    if (io.GetDimensions(a) == 0)
      throw_input_error(path, shape == Shape::planar ? "empty image (a dimension is 0)" : "empty volume (a dimension is 0)");
    const double s = io.GetSpacing(a);
    if (!std::isfinite(s) || s <= 0) {
      std::ostringstream text;
      text << "spacing along axis " << a << " is " << s << " mm (must be positive)";
      throw_input_error(path, text.str());
    }
  }
}

// A header that promises far more voxel bytes than its file can hold is refused before ITK
// allocates them (fuzzed NIfTI and NRRD headers asked for gigabytes from a few hundred bytes).
// Deflate expands at most 1032:1, and ITK reports rescaled NIfTI integers as float (up to 4 times
// the stored bytes). Detached data (.mhd, .nhdr) is another file's: the MetaImage and NRRD checks
// size it (and size attached NRRD data more tightly, by its encoding).
void check_size_against_file(itk::ImageIOBase& io, const std::string& path) {
  const std::string name = lower_file_name(path);
  if (ends_with(name, ".mhd") || ends_with(name, ".nhdr")) return;
  std::error_code ec;
  const double file_bytes = double(fs::file_size(path, ec));
  if (ec) return;
  double bytes = double(io.GetComponentSize()) * double(io.GetNumberOfComponents());
  for (unsigned a = 0; a < io.GetNumberOfDimensions(); ++a) bytes *= double(io.GetDimensions(a));
  if (bytes > 1032.0 * 4.0 * file_bytes)
    throw_input_error(path, "header describes " + std::to_string(uint64_t(bytes)) + " bytes of voxels, more than a " +
                                std::to_string(uint64_t(file_bytes)) + "-byte file can hold");
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

// The voxels of a checked scalar header (check_header: 3D, or 2D read one voxel deep). NIfTI and
// MetaImage files in the forms ITK writes are read by the project's own readers, straight into the
// volume's floats (float files) or through one buffer of the stored type, with the same static_cast
// conversion itk::ImageFileReader<float 3D> makes, and the geometry as that reader builds it from
// the IO (the direction's columns are the IO's axes). The reader would read the file into its image
// buffer and copy it out (for a 256^3 float CT, 64 MB more to fault in and copy); other files go
// through it. (Reading them through the IO into the volume instead let a fuzzed MetaImage corrupt
// the heap: CI's fuzz run of 2026-12-02.)
Volume read_voxels(itk::ImageIOBase& io, const std::string& path, const std::optional<NiftiVoxels>& nifti,
                   const std::optional<MetaImageVoxels>& metaimage) {
  if (!nifti && !metaimage) {
    auto reader = itk::ImageFileReader<ItkVolume>::New();
    reader->SetFileName(path);
    reader->SetImageIO(&io);
    reader->Update();
    return from_itk(*reader->GetOutput());
  }
  Volume v;
  // A 2D file (Shape::planar) has no third axis: one voxel deep, of unit spacing, along z, as
  // ITK's reader pads it.
  const unsigned dims = io.GetNumberOfDimensions();
  v.geometry.direction.setIdentity();
  for (unsigned a = 0; a < 3; ++a) {
    v.geometry.size[int(a)] = a < dims ? int(io.GetDimensions(a)) : 1;
    v.geometry.origin[int(a)] = a < dims ? io.GetOrigin(a) : 0.0;
    v.geometry.spacing[int(a)] = a < dims ? io.GetSpacing(a) : 1.0;
    if (a >= dims) continue;
    const std::vector<double> axis = io.GetDirection(a);
    // (+ 0: NIfTI's LPS flip leaves negative zeros, which itk::Image's direction does not keep.)
    for (unsigned b = 0; b < dims; ++b) v.geometry.direction(int(b), int(a)) = axis[b] + 0.0;
  }
  const size_t n = v.geometry.voxel_count();
  v.voxels = nifti ? read_nifti_voxels(path, *nifti, n) : read_metaimage_voxels(path, *metaimage, n);
  return v;
}

// The format's own header check of a NIfTI, MetaImage or NRRD file, by its name (nothing for any
// other name), with the voxels' layout where the project's own readers read them. These are the
// checks that find the layout: for a .nii.gz, check_nifti_header would inflate the whole file to
// check its length, and the read inflates it again.
struct FormatHeader {
  std::optional<NiftiVoxels> nifti;
  std::optional<MetaImageVoxels> metaimage;
};

FormatHeader check_format_header(const std::string& path) {
  const std::string name = lower_file_name(path);
  FormatHeader h;
  if (ends_with(name, ".nii") || ends_with(name, ".nii.gz"))
    h.nifti = check_nifti_header_for_voxels(path);
  else if (ends_with(name, ".mha") || ends_with(name, ".mhd"))
    h.metaimage = check_metaimage_header_for_voxels(path);
  else if (is_nrrd_name(name))
    check_nrrd_header(path);
  return h;
}

// The format's own header check comes first, by the file's name: ITK's NIfTI and MetaImage readers
// print to stderr, abort on a NaN orientation or miss truncation (engine/nifti_header.hpp,
// engine/metaimage_header.hpp). Whatever the libraries still print is kept from the terminal: a
// failure reports its first line, and a "successful" read that printed (MetaIO's "Uncompress
// failed" leaves garbage voxels) is refused.
// nullopt: the file is for GDCM, which only a read with `gdcm_allowed` asks (create_reader_io).
std::optional<Volume> read_file_volume(const std::string& path, bool gdcm_allowed, Shape shape = Shape::volume) {
  const auto [nifti, metaimage] = check_format_header(path);

  CapturedLibraryOutput library;
  const auto detail = [&library](const std::string& problem) {
    const std::string said = library.first_line();
    return said.empty() ? problem : problem + ": " + said;
  };
  bool for_gdcm = false;
  itk::ImageIOBase::Pointer io = create_reader_io(path, gdcm_allowed, for_gdcm);
  if (for_gdcm && !gdcm_allowed) return std::nullopt;
  // (No library detail here: it would be what the format probes, GDCM's among them, printed.)
  const std::string noun = shape == Shape::planar ? "image" : "volume";
  if (!io) throw_input_error(path, "unknown or unreadable " + noun + " format");
  io->SetFileName(path);
  try {
    io->ReadImageInformation();
  } catch (const itk::ExceptionObject&) {
    throw_input_error(path, detail("cannot read " + noun + " header (unreadable or corrupt file)"));
  }
  check_header(*io, path, shape);
  check_size_against_file(*io, path);

  Volume v;
  try {
    // A layout only when ITK also took the file for that format (a .nii name is probed by content,
    // though check_nifti_header_for_voxels has refused anything else already).
    const bool is_nifti = dynamic_cast<itk::NiftiImageIO*>(io.GetPointer()) != nullptr;
    const bool is_metaimage = dynamic_cast<itk::MetaImageIO*>(io.GetPointer()) != nullptr;
    v = read_voxels(*io, path, is_nifti ? nifti : std::nullopt, is_metaimage ? metaimage : std::nullopt);
  } catch (const itk::ExceptionObject&) {
    // ITK's description is a multi-line dump naming its own source files; the user needs the file.
    throw_input_error(path, detail("cannot read " + noun + " (file truncated or corrupt)"));
  } catch (const std::bad_alloc&) {
    // MetaIO sizes some buffers from the header (a corrupt compressed size asked for 2^64 bytes).
    throw_input_error(path, "cannot read " + noun + " (its header asks for more memory than there is)");
  }
  if (const std::string said = library.first_line(); !said.empty())
    throw_input_error(path, "corrupt " + noun + " data (the reader reported: " + said + ")");
  return v;
}

// GDCM's scan of a directory parses every file in it (not its subdirectories), so each DICOM file
// there is checked first (engine/dicom_file_check.hpp); a bad one is named in the refusal.
void check_series_directory(const std::string& path) {
  std::error_code ec;
  for (const fs::directory_entry& entry : fs::directory_iterator(path, ec)) {
    std::error_code type_ec;
    if (!entry.is_regular_file(type_ec)) continue;
    const std::string file = entry.path().string();
    if (has_dicom_magic(file)) check_dicom_file(file);
  }
  if (ec) throw_input_error(path, "cannot list the directory (" + ec.message() + ")");
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
    for (std::vector<std::string>& series : dicom_library().series_files(path))
      if (series.size() > files.size()) files = std::move(series);
  } catch (const itk::ExceptionObject&) {
    itk::Object::SetGlobalWarningDisplay(warnings);
    throw_input_error(path, "cannot scan directory for DICOM series");
  }
  itk::Object::SetGlobalWarningDisplay(warnings);
  if (files.empty()) throw_input_error(path, "directory holds no DICOM series");

  itk::ImageIOBase::Pointer io = dicom_library().new_image_io();
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

// A volume as the bytes a child process hands back (engine/isolated_read.hpp): the geometry, then
// the voxels.
struct GeometryBytes {
  int32_t size[3];
  double origin[3], spacing[3], direction[9];  // direction column by column (Eigen's order)
};

void write_volume_bytes(const Volume& v, const IsolatedWrite& write) {
  GeometryBytes g{};
  for (int a = 0; a < 3; ++a) {
    g.size[a] = v.geometry.size[a];
    g.origin[a] = v.geometry.origin[a];
    g.spacing[a] = v.geometry.spacing[a];
  }
  std::memcpy(g.direction, v.geometry.direction.data(), sizeof g.direction);
  write(&g, sizeof g);
  write(v.voxels.data(), v.voxels.size() * sizeof(float));
}

Volume volume_from_bytes(std::string_view bytes) {
  GeometryBytes g{};
  if (bytes.size() < sizeof g) throw std::runtime_error("read_volume: a child's answer lacks the geometry");
  std::memcpy(&g, bytes.data(), sizeof g);
  Volume v;
  for (int a = 0; a < 3; ++a) {
    v.geometry.size[a] = g.size[a];
    v.geometry.origin[a] = g.origin[a];
    v.geometry.spacing[a] = g.spacing[a];
  }
  std::memcpy(v.geometry.direction.data(), g.direction, sizeof g.direction);
  const size_t n = v.geometry.voxel_count();
  if ((v.geometry.size.array() < 0).any() || bytes.size() - sizeof g != n * sizeof(float))
    throw std::runtime_error("read_volume: a child's answer does not hold the voxels its geometry describes");
  v.voxels.resize(n);
  std::memcpy(v.voxels.data(), bytes.data() + sizeof g, n * sizeof(float));
  return v;
}

}  // namespace

Volume read_volume(const std::string& path) {
  quiet_library_output();
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!fs::exists(status)) throw_input_error(path, "file not found");
  const bool directory = fs::is_directory(status);
  std::optional<Volume> v;
  if (!directory) v = read_file_volume(path, /*gdcm_allowed=*/false);
  if (!v) {
    // A series directory, or a file for GDCM: everything GDCM would parse is checked here first
    // (engine/dicom_file_check.hpp); then, as GDCM may still abort the process on a malformed
    // file, it reads in a child process (engine/isolated_read.hpp), which hands back the volume.
    if (directory)
      check_series_directory(path);
    else
      check_dicom_file(path);
    dicom_library();  // loaded here, not in the child
    const auto produce = [&](const IsolatedWrite& write) {
      write_volume_bytes(directory ? read_dicom_series(path) : *read_file_volume(path, /*gdcm_allowed=*/true), write);
    };
    run_isolated_read(path, "GDCM (the DICOM library)", produce, [&](std::string_view bytes) { v = volume_from_bytes(bytes); });
  }
  validate_volume(*v, path);
  return std::move(*v);
}

Volume read_planar_volume(const std::string& path) {
  quiet_library_output();
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!fs::exists(status)) throw_input_error(path, "file not found");
  if (fs::is_directory(status)) throw_input_error(path, "is a directory, expected an image file");
  // No GDCM here: a DICOM image is read_image's own case (a single frame, in a child process).
  std::optional<Volume> v = read_file_volume(path, /*gdcm_allowed=*/false, Shape::planar);
  if (!v) throw_input_error(path, "unknown or unreadable image format");
  validate_volume(*v, path);
  return std::move(*v);
}

bool is_volume_file_name(const std::string& path) {
  const std::string name = lower_file_name(path);
  for (const char* e : {".nii", ".nii.gz", ".mha", ".mhd", ".nrrd", ".nhdr"})
    if (ends_with(name, e)) return true;
  return false;
}

bool is_2d_image_file(const std::string& path) {
  if (!is_volume_file_name(path)) return false;
  check_format_header(path);
  CapturedLibraryOutput library;
  bool for_gdcm = false;
  itk::ImageIOBase::Pointer io = create_reader_io(path, /*gdcm_allowed=*/false, for_gdcm);
  if (!io) return false;
  io->SetFileName(path);
  try {
    io->ReadImageInformation();
  } catch (const itk::ExceptionObject&) {
    return false;  // read_volume says what is wrong with it
  }
  return io->GetNumberOfDimensions() == 2;
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
