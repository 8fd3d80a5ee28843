#pragma once
// Reading back, with ITK's own readers, the files the program writes for other tools: transform
// files (.tfm, .h5) and spaced 2D images (.mha, .nrrd).
#include <gtest/gtest.h>
#include <itkHDF5TransformIOFactory.h>
#include <itkImage.h>
#include <itkImageFileReader.h>
#include <itkMatrixOffsetTransformBase.h>
#include <itkTransformFileReader.h>
#include <itkTxtTransformIOFactory.h>

#include <Eigen/Geometry>
#include <string>

namespace fluoro::test {

// The file's one transform as the 4x4 map it applies to points (ITK: fixed to moving), and its
// class name.
inline Eigen::Matrix4d read_itk_transform(const std::string& path, std::string* class_name = nullptr) {
  static const bool registered = [] {  // once per process, as the engine's writer does
    itk::ObjectFactoryBase::RegisterFactory(itk::TxtTransformIOFactory::New());
    itk::ObjectFactoryBase::RegisterFactory(itk::HDF5TransformIOFactory::New());
    return true;
  }();
  (void)registered;
  auto reader = itk::TransformFileReaderTemplate<double>::New();
  reader->SetFileName(path);
  reader->Update();
  EXPECT_EQ(reader->GetTransformList()->size(), 1u);
  const auto* t = dynamic_cast<const itk::MatrixOffsetTransformBase<double, 3, 3>*>(reader->GetTransformList()->front().GetPointer());
  EXPECT_NE(t, nullptr) << path;
  if (class_name) *class_name = reader->GetTransformList()->front()->GetNameOfClass();
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  if (!t) return m;
  // Through TransformPoint, not the stored parameters: what any ITK user would get.
  const auto origin = t->TransformPoint(itk::Point<double, 3>());
  for (int c = 0; c < 3; ++c) {
    itk::Point<double, 3> e;
    e.Fill(0);
    e[c] = 1;
    const auto p = t->TransformPoint(e);
    for (int r = 0; r < 3; ++r) m(r, c) = p[r] - origin[r];
  }
  for (int r = 0; r < 3; ++r) m(r, 3) = origin[r];
  return m;
}

using ItkImage2f = itk::Image<float, 2>;
inline ItkImage2f::Pointer read_itk_image_2d(const std::string& path) {
  auto reader = itk::ImageFileReader<ItkImage2f>::New();
  reader->SetFileName(path);
  reader->Update();
  return reader->GetOutput();
}

}  // namespace fluoro::test
