#include "engine/dicom_library.hpp"

#include <cstring>
#include <mutex>
#include <stdexcept>

#include "engine/plugin_build_id.hpp"
#include "engine/plugin_loader.hpp"

namespace fluoro {
namespace {

void check_build(const char* module, const char* build_id) {
  if (!build_id || std::strcmp(build_id, kPluginBuildId) != 0)
    throw std::runtime_error(std::string("the module ") + module + " is from another build of fluoro (" +
                             (build_id ? build_id : "unknown") + "; this is " + kPluginBuildId + ")");
}

}  // namespace

const DicomLibrary& dicom_library() {
  static const DicomLibrary* library = [] {
    using Entry = const DicomLibrary* (*)();
    const auto* l = reinterpret_cast<Entry>(plugin_symbol("fluoro_dicom", "fluoro_dicom_library_v1"))();
    check_build("libfluoro_dicom.so", l ? l->build_id : nullptr);
    if (l->size != sizeof(DicomLibrary)) throw std::runtime_error("the module libfluoro_dicom.so has another interface");
    return l;
  }();
  return *library;
}

void register_hdf5_transform_io() {
  static std::once_flag registered;
  std::call_once(registered, [] {
    using Entry = const char* (*)();
    check_build("libfluoro_hdf5.so", reinterpret_cast<Entry>(plugin_symbol("fluoro_hdf5", "fluoro_hdf5_register_v1"))());
  });
}

}  // namespace fluoro
