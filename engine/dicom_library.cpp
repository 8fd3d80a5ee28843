#include "engine/dicom_library.hpp"

#include <stdexcept>

#include "engine/plugin_loader.hpp"

namespace fluoro {

const DicomLibrary& dicom_library() {
  static const DicomLibrary* library = [] {
    using Entry = const DicomLibrary* (*)();
    const auto* l = reinterpret_cast<Entry>(plugin_symbol("fluoro_dicom", "fluoro_dicom_library_v1"))();
    check_plugin_build("fluoro_dicom", l ? l->build_id : nullptr);
    if (l->size != sizeof(DicomLibrary)) throw std::runtime_error("the module libfluoro_dicom.so has another interface");
    return l;
  }();
  return *library;
}

}  // namespace fluoro
