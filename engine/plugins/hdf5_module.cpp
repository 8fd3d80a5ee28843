// libfluoro_hdf5.so: ITK's HDF5 transform files, registered only by writes of .h5 and .hdf5
// (engine/itk_transform_writer.cpp, register_hdf5_transform_io).
#include <itkHDF5TransformIOFactory.h>

#include "engine/plugin_build_id.hpp"

extern "C" __attribute__((visibility("default"))) const char* fluoro_hdf5_register_v1() {
  itk::ObjectFactoryBase::RegisterFactory(itk::HDF5TransformIOFactory::New());
  return fluoro::kPluginBuildId;
}
