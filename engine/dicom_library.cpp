#include "engine/dicom_library.hpp"

#include <cstring>
#include <mutex>
#include <stdexcept>

#include "engine/plugin_loader.hpp"
#include "engine/version.hpp"

namespace fluoro {

const DicomLibrary& dicom_library() {
  static const DicomLibrary* library = [] {
    using Entry = const DicomLibrary* (*)();
    const auto* l = reinterpret_cast<Entry>(plugin_symbol("fluoro_dicom", "fluoro_dicom_library_v1"))();
    if (!l || !l->version || std::strcmp(l->version, kVersion) != 0)
      throw std::runtime_error(std::string("the module libfluoro_dicom.so is from fluoro ") +
                               (l && l->version ? l->version : "(unknown)") + ", this is fluoro " + kVersion);
    return l;
  }();
  return *library;
}

void register_hdf5_transform_io() {
  static std::once_flag registered;
  std::call_once(registered, [] {
    using Entry = const char* (*)();
    const char* version = reinterpret_cast<Entry>(plugin_symbol("fluoro_hdf5", "fluoro_hdf5_register_v1"))();
    if (!version || std::strcmp(version, kVersion) != 0)
      throw std::runtime_error(std::string("the module libfluoro_hdf5.so is from fluoro ") +
                               (version ? version : "(unknown)") + ", this is fluoro " + kVersion);
  });
}

}  // namespace fluoro
