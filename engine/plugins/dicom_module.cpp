// libfluoro_dicom.so: GDCM behind engine/dicom_library.hpp, loaded only by reads of DICOM.
#include <itkGDCMImageIO.h>
#include <itkGDCMSeriesFileNames.h>

#include "engine/dicom_library.hpp"
#include "engine/plugin_build_id.hpp"

namespace {

itk::ImageIOBase::Pointer new_image_io() { return itk::GDCMImageIO::New().GetPointer(); }

std::vector<std::vector<std::string>> series_files(const std::string& directory) {
  auto names = itk::GDCMSeriesFileNames::New();
  names->SetUseSeriesDetails(true);
  names->SetDirectory(directory);
  std::vector<std::vector<std::string>> series;
  for (const std::string& uid : names->GetSeriesUIDs()) series.push_back(names->GetFileNames(uid));
  return series;
}

const fluoro::DicomLibrary library{fluoro::kPluginBuildId, sizeof(fluoro::DicomLibrary), &new_image_io, &series_files};

}  // namespace

extern "C" __attribute__((visibility("default"))) const fluoro::DicomLibrary* fluoro_dicom_library_v1() {
  return &library;
}
