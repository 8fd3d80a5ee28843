#pragma once
// GDCM, ITK's DICOM reader, through the module libfluoro_dicom.so (engine/plugin_loader.hpp):
// linked into the program it took 0.04 s of every command's start-up, DICOM or not.
#include <itkImageIOBase.h>

#include <cstddef>
#include <string>
#include <vector>

namespace fluoro {

struct DicomLibrary {
  const char* build_id;  // kPluginBuildId of the module's build (engine/plugin_build_id.hpp)
  size_t size;           // sizeof(DicomLibrary) there
  // A new GDCMImageIO.
  itk::ImageIOBase::Pointer (*new_image_io)();
  // The DICOM series in a directory (GDCMSeriesFileNames with its series details), each as its
  // files in slice order. Throws itk::ExceptionObject when the scan fails.
  std::vector<std::vector<std::string>> (*series_files)(const std::string& directory);
};

// Loads the module at the first call (std::runtime_error when it cannot, or when it is from
// another build). Call it before forking a child that reads DICOM (engine/isolated_read.hpp),
// so that the child never loads a library.
const DicomLibrary& dicom_library();

}  // namespace fluoro
