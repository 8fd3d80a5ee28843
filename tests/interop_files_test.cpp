// engine/itk_transform_writer and engine/spaced_image_writer, read back with ITK's readers: the
// transform file holds T_world_ct^-1 (ITK's fixed-to-moving direction), the image its spacing,
// origin and pixels with row 0 first. About 0.1 s (ITK's HDF5 transform IO is most of it).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "engine/error.hpp"
#include "engine/itk_transform_writer.hpp"
#include "engine/spaced_image_writer.hpp"
#include "tests/itk_files.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

class InteropFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("fluoro_interop_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST_F(InteropFiles, TransformFilesHoldTheWorldToCtMap) {
  const Pose T_world_ct = pose_from_rotation_vector(Eigen::Vector3d(0.3, -0.2, 0.5), Eigen::Vector3d(12.5, -40, 700));
  // .h5 first: the HDF5 factory must then come from the engine's module (engine/plugins),
  // not from read_itk_transform's own registration (ctest runs each test in its own process).
  for (const char* name : {"pose.h5", "pose.tfm"}) {
    write_itk_transform(T_world_ct, path(name));
    std::string cls;
    const Eigen::Matrix4d m = test::read_itk_transform(path(name), &cls);
    EXPECT_EQ(cls, "AffineTransform") << name;
    // A world point goes to the CT point that the pose puts there.
    const Eigen::Vector3d ct(10, -20, 30), world = T_world_ct * ct;
    EXPECT_LT(((m * world.homogeneous()).head<3>() - ct).norm(), 1e-9) << name;
    EXPECT_LT((m - T_world_ct.inverse().matrix()).cwiseAbs().maxCoeff(), 1e-12) << name;
  }
  EXPECT_THROW(write_itk_transform(T_world_ct, path("pose.mat")), InputError);
  EXPECT_FALSE(fs::exists(path("pose.mat")));
}

TEST_F(InteropFiles, SpacedImagesKeepSpacingOriginAndRows) {
  Image image(5, 3);
  for (int v = 0; v < 3; ++v)
    for (int u = 0; u < 5; ++u) image.at(u, v) = float(10 * v + u) + 0.25f;
  for (const char* name : {"d.mha", "d.nrrd"}) {
    write_spaced_image(image, Eigen::Vector2d(0.3, 0.4), Eigen::Vector2d(6, 8), path(name));
    const auto back = test::read_itk_image_2d(path(name));
    ASSERT_EQ(back->GetLargestPossibleRegion().GetSize()[0], 5u) << name;
    ASSERT_EQ(back->GetLargestPossibleRegion().GetSize()[1], 3u) << name;
    EXPECT_DOUBLE_EQ(back->GetSpacing()[0], 0.3) << name;
    EXPECT_DOUBLE_EQ(back->GetSpacing()[1], 0.4) << name;
    EXPECT_DOUBLE_EQ(back->GetOrigin()[0], 6) << name;
    EXPECT_DOUBLE_EQ(back->GetOrigin()[1], 8) << name;
    for (int v = 0; v < 3; ++v)
      for (int u = 0; u < 5; ++u) EXPECT_EQ(back->GetPixel({{u, v}}), image.at(u, v)) << name << " " << u << "," << v;
  }
  EXPECT_THROW(write_spaced_image(image, Eigen::Vector2d(1, 1), Eigen::Vector2d::Zero(), path("d.mhd")), InputError);
}

}  // namespace
}  // namespace fluoro
