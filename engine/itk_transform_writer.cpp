#include "engine/itk_transform_writer.hpp"

#include <itkAffineTransform.h>
#include <itkTransformFileWriter.h>
#include <itkTxtTransformIOFactory.h>

#include <mutex>

#include "engine/atomic_file.hpp"
#include "engine/error.hpp"
#include "engine/file_names.hpp"
#include "engine/plugin_loader.hpp"

namespace fluoro {
namespace {

// ITK's HDF5 transform IO lives in the module libfluoro_hdf5.so (engine/plugins/hdf5_module.cpp),
// whose entry point registers its factory: linked into the program, HDF5 brought 34 libraries and
// 0.02 s of start-up to every command.
void register_hdf5_transform_io() {
  static std::once_flag registered;
  std::call_once(registered, [] {
    using Entry = const char* (*)();
    check_plugin_build("fluoro_hdf5", reinterpret_cast<Entry>(plugin_symbol("fluoro_hdf5", "fluoro_hdf5_register_v1"))());
  });
}

}  // namespace

bool is_itk_transform_path(const std::string& path) {
  const std::string ext = lower_extension(path);
  return ext == ".tfm" || ext == ".txt" || ext == ".h5" || ext == ".hdf5";
}

void prepare_itk_transform_writer(const std::string& path) {
  static std::once_flag registered;
  std::call_once(registered, [] { itk::ObjectFactoryBase::RegisterFactory(itk::TxtTransformIOFactory::New()); });
  // HDF5 from its module, only for its files.
  const std::string ext = lower_extension(path);
  if (ext == ".h5" || ext == ".hdf5") register_hdf5_transform_io();
}

void write_itk_transform(const Pose& T_world_ct, const std::string& path) {
  if (!is_itk_transform_path(path))
    throw_input_error(path, "unsupported transform file extension (use .tfm, .txt, .h5 or .hdf5)");
  // Registered here, not by ITK's factory-registration headers: the engine is also a library whose
  // users' link lines must not depend on a generated header's static initialisers.
  prepare_itk_transform_writer(path);
  const Pose T_ct_world = T_world_ct.inverse();
  using Transform = itk::AffineTransform<double, 3>;
  auto transform = Transform::New();
  Transform::MatrixType m;
  Transform::OutputVectorType t;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m(r, c) = T_ct_world.linear()(r, c);
    t[r] = T_ct_world.translation()(r);
  }
  transform->SetMatrix(m);
  transform->SetTranslation(t);
  write_file_atomic(path, [&](const std::string& file) {
    auto writer = itk::TransformFileWriterTemplate<double>::New();
    writer->SetFileName(file);
    writer->SetInput(transform);
    try {
      writer->Update();
    } catch (const itk::ExceptionObject& e) {
      throw std::runtime_error(std::string("ITK transform writer: ") + e.GetDescription());
    }
  });
}

}  // namespace fluoro
