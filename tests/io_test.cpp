// File I/O: atomic writes, volume/image/JSON round trips, and one-line InputErrors for bad files.

#include <gtest/gtest.h>
#include <itkGDCMImageIO.h>
#include <itkImage.h>
#include <itkImageFileReader.h>
#include <itkImageFileWriter.h>
#include <itkImageSeriesWriter.h>
#include <itkMetaDataObject.h>
#include <itkNumericSeriesFileNames.h>
#include <unistd.h>
#include <zlib.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "engine/atomic_file.hpp"
#include "engine/error.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "engine/metaimage_header.hpp"
#include "engine/spaced_image_writer.hpp"
#include "engine/volume_io.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

class IoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::path(::testing::TempDir()) /
           ("fluoro_io_" + std::string(info->name()) + "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string file(const std::string& name) const { return (dir_ / name).string(); }
  // Every entry of the directory: a leftover temporary shows up here.
  std::vector<std::string> listing() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_))
      names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

  fs::path dir_;
};

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void spit(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

// Runs f, which must throw InputError whose one-line message names `path` and contains `word`.
template <class F>
void expect_input_error(F&& f, const std::string& path, const std::string& word) {
  try {
    f();
    ADD_FAILURE() << "no InputError for " << path << " (expected \"" << word << "\")";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find(word), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
}

// ---- atomic writes ------------------------------------------------------------------------

TEST_F(IoTest, AtomicWriteReplacesTargetAndKeepsCompoundExtension) {
  const std::string target = file("out.nii.gz");
  spit(target, "old");
  std::string seen;
  write_file_atomic(target, [&](const std::string& tmp) {
    seen = tmp;
    spit(tmp, "new");
  });
  EXPECT_EQ(slurp(target), "new");
  EXPECT_EQ(fs::path(seen).parent_path(), dir_);
  EXPECT_NE(seen, target);
  EXPECT_TRUE(seen.ends_with(".nii.gz")) << seen;
  EXPECT_EQ(listing(), std::vector<std::string>{"out.nii.gz"});
}

TEST_F(IoTest, AtomicWriteFailureLeavesOldFileAndNoTemporary) {
  const std::string target = file("result.json");
  spit(target, "old contents");
  EXPECT_THROW(write_file_atomic(target,
                                 [](const std::string& tmp) {
                                   spit(tmp, "half writ");
                                   throw std::runtime_error("writer failed midway");
                                 }),
               std::runtime_error);
  EXPECT_EQ(slurp(target), "old contents");
  EXPECT_EQ(listing(), std::vector<std::string>{"result.json"});
}

TEST_F(IoTest, AtomicWriteIntoMissingDirectoryIsInputError) {
  const std::string target = file("no/such/dir/out.png");
  expect_input_error([&] { write_file_atomic(target, [](const std::string&) {}); }, target,
                     "directory");
}

TEST_F(IoTest, WriteJsonFailingMidwayLeavesOldFile) {
  const std::string target = file("camera.json");
  write_json(nlohmann::json{{"a", 1}}, target);
  const std::string before = slurp(target);
  // Invalid UTF-8 makes dump() throw after the temporary has been created.
  const nlohmann::json bad = {{"name", std::string("\xff\xfe")}};
  // Any failure while writing is reported against the target path, as bad output.
  EXPECT_THROW(write_json(bad, target), InputError);
  EXPECT_EQ(slurp(target), before);
  EXPECT_EQ(listing(), std::vector<std::string>{"camera.json"});
}

TEST_F(IoTest, WriteJsonIsPrettyWithTrailingNewline) {
  const std::string target = file("doc.json");
  write_json(nlohmann::json{{"a", {1, 2}}}, target);
  EXPECT_EQ(slurp(target), "{\n  \"a\": [\n    1,\n    2\n  ]\n}\n");
}

// ---- volumes ------------------------------------------------------------------------------

Volume make_volume(const Eigen::Matrix3d& direction) {
  Volume v;
  v.geometry.size = {7, 5, 4};
  v.geometry.origin = {-120.25, 33.5, 10.0};
  v.geometry.spacing = {0.5, 0.75, 2.5};
  v.geometry.direction = direction;
  v.voxels.resize(v.geometry.voxel_count());
  for (size_t n = 0; n < v.voxels.size(); ++n) v.voxels[n] = float(int(n * 37 % 2001) - 1000);
  v.voxels[3] = 0.125f;  // a non-integer survives float formats
  return v;
}

// Proper, non-identity, short decimals: every format stores it exactly.
Eigen::Matrix3d permuted_direction() {
  Eigen::Matrix3d d;
  d << 0, -1, 0,  //
      1, 0, 0,    //
      0, 0, 1;
  return d;
}

Eigen::Matrix3d oblique_direction() {
  return (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

void expect_same_volume(const Volume& a, const Volume& b, double geometry_tol) {
  EXPECT_EQ(a.geometry.size, b.geometry.size);
  EXPECT_LE((a.geometry.origin - b.geometry.origin).cwiseAbs().maxCoeff(), geometry_tol)
      << b.geometry.origin.transpose();
  EXPECT_LE((a.geometry.spacing - b.geometry.spacing).cwiseAbs().maxCoeff(), geometry_tol)
      << b.geometry.spacing.transpose();
  EXPECT_LE((a.geometry.direction - b.geometry.direction).cwiseAbs().maxCoeff(), geometry_tol)
      << b.geometry.direction;
  EXPECT_EQ(a.voxels, b.voxels);
}

TEST_F(IoTest, VolumeRoundTripsExactly) {
  const Volume v = make_volume(permuted_direction());
  for (const char* name : {"ct.nii.gz", "ct.nii", "ct.mha", "ct.mhd", "ct.nrrd"}) {
    SCOPED_TRACE(name);
    write_volume(v, file(name));
    expect_same_volume(v, read_volume(file(name)), 0.0);
  }
}

// Voxels 0..n-1 of type T with the test volume's geometry, written by ITK's own writer.
template <class T>
void write_typed_volume(const std::string& path, const Volume& like, bool compress = false) {
  using TypedImage = itk::Image<T, 3>;
  auto image = TypedImage::New();
  typename TypedImage::SizeType size;
  typename TypedImage::PointType origin;
  typename TypedImage::SpacingType spacing;
  typename TypedImage::DirectionType direction;
  for (unsigned a = 0; a < 3; ++a) {
    size[a] = itk::SizeValueType(like.geometry.size[int(a)]);
    origin[a] = like.geometry.origin[int(a)];
    spacing[a] = like.geometry.spacing[int(a)];
    for (unsigned b = 0; b < 3; ++b) direction(a, b) = like.geometry.direction(int(a), int(b));
  }
  image->SetRegions(typename TypedImage::RegionType(size));
  image->SetOrigin(origin);
  image->SetSpacing(spacing);
  image->SetDirection(direction);
  image->Allocate();
  T* p = image->GetBufferPointer();
  const size_t n = like.geometry.voxel_count();
  // Extremes of the type (where a float rounds them; a double's are beyond float, which
  // validate_volume refuses) and values on both sides of 0 when signed.
  const T high = std::is_same_v<T, double> ? T(1e30) : std::numeric_limits<T>::max();
  const T low = std::is_same_v<T, double> ? T(-1e30) : std::numeric_limits<T>::lowest();
  for (size_t i = 0; i < n; ++i) p[i] = i == 0 ? high : i == 1 ? low : T(int(i % 97) - 40);
  auto writer = itk::ImageFileWriter<TypedImage>::New();
  writer->SetFileName(path);
  writer->SetInput(image);
  writer->SetUseCompression(compress);
  writer->Update();
}

// What itk::ImageFileReader<float 3D> makes of a file: the reading read_volume replaced.
Volume read_with_itk_reader(const std::string& path) {
  using FloatImage = itk::Image<float, 3>;
  auto reader = itk::ImageFileReader<FloatImage>::New();
  reader->SetFileName(path);
  reader->Update();
  const FloatImage& image = *reader->GetOutput();
  Volume v;
  for (int a = 0; a < 3; ++a) {
    v.geometry.size[a] = int(image.GetLargestPossibleRegion().GetSize()[unsigned(a)]);
    v.geometry.origin[a] = image.GetOrigin()[unsigned(a)];
    v.geometry.spacing[a] = image.GetSpacing()[unsigned(a)];
    for (int b = 0; b < 3; ++b) v.geometry.direction(a, b) = image.GetDirection()(unsigned(a), unsigned(b));
  }
  v.voxels.assign(image.GetBufferPointer(), image.GetBufferPointer() + v.geometry.voxel_count());
  return v;
}

template <class T>
void expect_read_as_itk_reads(const std::string& path, const Volume& like, bool compress) {
  SCOPED_TRACE(path);
  write_typed_volume<T>(path, like, compress);
  expect_same_volume(read_with_itk_reader(path), read_volume(path), 0.0);
  // What ITK writes is what the MetaImage reader reads itself (all but MET_LONG, which ITK's writer
  // never writes here: a long is 8 bytes).
  if (path.ends_with(".mha")) {
    EXPECT_TRUE(check_metaimage_header_for_voxels(path));
  }
}

// read_volume reads NIfTI and MetaImage voxels itself (other formats through
// itk::ImageFileReader); every stored type must still come out as that reader gives it.
TEST_F(IoTest, EveryVoxelTypeReadsAsItksReaderReadsIt) {
  const Volume like = make_volume(permuted_direction());
  for (const auto& [ext, compress] : {std::pair{".nii", false}, {".nii.gz", false}, {".nrrd", false},
                                      {".mha", false}, {".z.mha", true}}) {
    const std::string stem = file("typed");
    expect_read_as_itk_reads<uint8_t>(stem + "_u8" + ext, like, compress);
    expect_read_as_itk_reads<int8_t>(stem + "_i8" + ext, like, compress);
    expect_read_as_itk_reads<int16_t>(stem + "_i16" + ext, like, compress);
    expect_read_as_itk_reads<uint16_t>(stem + "_u16" + ext, like, compress);
    expect_read_as_itk_reads<int32_t>(stem + "_i32" + ext, like, compress);
    expect_read_as_itk_reads<uint32_t>(stem + "_u32" + ext, like, compress);
    expect_read_as_itk_reads<int64_t>(stem + "_i64" + ext, like, compress);
    expect_read_as_itk_reads<uint64_t>(stem + "_u64" + ext, like, compress);
    expect_read_as_itk_reads<float>(stem + "_f32" + ext, like, compress);
    expect_read_as_itk_reads<double>(stem + "_f64" + ext, like, compress);
  }
  // A real CT (int16, gzipped NIfTI, an LPS flip of the stored RAS axes), when the data is there.
  const std::string pelvis = std::string(FLUORO_SHARED_DATASETS) + "/pelvis-ct/ct.nii.gz";
  if (fs::exists(pelvis)) expect_same_volume(read_with_itk_reader(pelvis), read_volume(pelvis), 0.0);
}

TEST_F(IoTest, ObliqueVolumeRoundTrips) {
  const Volume v = make_volume(oblique_direction());
  // NIfTI keeps its geometry in single precision (quaternion + float offsets).
  for (const auto& [name, tol] :
       {std::pair{"ob.nii.gz", 1e-5}, {"ob.mha", 1e-6}, {"ob.nrrd", 1e-12}}) {
    SCOPED_TRACE(name);
    write_volume(v, file(name));
    expect_same_volume(v, read_volume(file(name)), tol);
  }
}

TEST_F(IoTest, MhdWritesHeaderAndRawBesideIt) {
  write_volume(make_volume(permuted_direction()), file("ct.mhd"));
  EXPECT_EQ(listing(), (std::vector<std::string>{"ct.mhd", "ct.raw"}));
}

TEST_F(IoTest, WriteVolumeRejectsUnknownExtension) {
  const std::string path = file("ct.vtk");
  expect_input_error([&] { write_volume(make_volume(permuted_direction()), path); }, path,
                     "extension");
}

TEST_F(IoTest, DicomSeriesRoundTrips) {
  const Volume v = make_volume(permuted_direction());
  using Short3 = itk::Image<short, 3>;
  using Short2 = itk::Image<short, 2>;
  auto image = Short3::New();
  Short3::SizeType size;
  Short3::PointType origin;
  Short3::SpacingType spacing;
  Short3::DirectionType direction;
  for (int a = 0; a < 3; ++a) {
    size[a] = itk::SizeValueType(v.geometry.size[a]);
    origin[a] = v.geometry.origin[a];
    spacing[a] = v.geometry.spacing[a];
    for (int b = 0; b < 3; ++b) direction(a, b) = v.geometry.direction(a, b);
  }
  image->SetRegions(Short3::RegionType(size));
  image->SetOrigin(origin);
  image->SetSpacing(spacing);
  image->SetDirection(direction);
  image->Allocate();
  Volume expected = v;
  for (size_t n = 0; n < v.voxels.size(); ++n) {
    image->GetBufferPointer()[n] = short(std::lround(v.voxels[n]));
    expected.voxels[n] = float(image->GetBufferPointer()[n]);
  }

  // One dictionary per slice: the series reader rebuilds the geometry from these tags.
  const fs::path series = dir_ / "series";
  fs::create_directories(series);
  std::vector<itk::MetaDataDictionary> dictionaries(size[2]);
  itk::ImageSeriesWriter<Short3, Short2>::DictionaryArrayType dictionary_array;
  const auto str = [](double x) {
    std::ostringstream s;
    s << x;
    return s.str();
  };
  const auto& d = v.geometry.direction;
  for (size_t k = 0; k < dictionaries.size(); ++k) {
    auto& dict = dictionaries[k];
    const Eigen::Vector3d p = v.geometry.index_to_physical(Eigen::Vector3d(0, 0, double(k)));
    itk::EncapsulateMetaData<std::string>(dict, "0008|0060", "CT");
    itk::EncapsulateMetaData<std::string>(dict, "0028|0004", "MONOCHROME2");
    itk::EncapsulateMetaData<std::string>(dict, "0008|0016", "1.2.840.10008.5.1.4.1.1.2");
    itk::EncapsulateMetaData<std::string>(dict, "0008|0018",
                                          "1.2.826.0.1.3680043.9.7.1." + std::to_string(k + 1));
    itk::EncapsulateMetaData<std::string>(dict, "0020|000d", "1.2.826.0.1.3680043.9.7.2");
    itk::EncapsulateMetaData<std::string>(dict, "0020|000e", "1.2.826.0.1.3680043.9.7.3");
    itk::EncapsulateMetaData<std::string>(dict, "0020|0013", std::to_string(k + 1));
    itk::EncapsulateMetaData<std::string>(dict, "0020|0032",
                                          str(p.x()) + "\\" + str(p.y()) + "\\" + str(p.z()));
    itk::EncapsulateMetaData<std::string>(dict, "0020|0037",
                                          str(d(0, 0)) + "\\" + str(d(1, 0)) + "\\" + str(d(2, 0)) +
                                              "\\" + str(d(0, 1)) + "\\" + str(d(1, 1)) + "\\" +
                                              str(d(2, 1)));
    itk::EncapsulateMetaData<std::string>(dict, "0028|0030",
                                          str(spacing[1]) + "\\" + str(spacing[0]));
    itk::EncapsulateMetaData<std::string>(dict, "0018|0050", str(spacing[2]));
    dictionary_array.push_back(&dict);
  }
  auto names = itk::NumericSeriesFileNames::New();
  names->SetSeriesFormat((series / "IM%04d.dcm").string());
  names->SetStartIndex(1);
  names->SetEndIndex(itk::SizeValueType(size[2]));
  names->SetIncrementIndex(1);
  auto io = itk::GDCMImageIO::New();
  io->KeepOriginalUIDOn();
  auto writer = itk::ImageSeriesWriter<Short3, Short2>::New();
  writer->SetInput(image);
  writer->SetImageIO(io);
  writer->SetFileNames(names->GetFileNames());
  writer->SetMetaDataDictionaryArray(&dictionary_array);
  writer->Update();

  expect_same_volume(expected, read_volume(series.string()), 1e-9);
}

TEST_F(IoTest, DirectoryWithoutDicomIsInputError) {
  spit(file("notes.txt"), "no images here");
  expect_input_error([&] { read_volume(dir_.string()); }, dir_.string(), "DICOM");
}

TEST_F(IoTest, MissingVolumeIsInputError) {
  const std::string path = file("nothing.nii.gz");
  expect_input_error([&] { read_volume(path); }, path, "not found");
}

TEST_F(IoTest, TruncatedVolumeIsInputError) {
  Volume v = make_volume(permuted_direction());
  v.geometry.size = {32, 32, 32};
  v.voxels.resize(v.geometry.voxel_count());
  for (size_t n = 0; n < v.voxels.size(); ++n) v.voxels[n] = float((n * 7919) % 3001);
  for (const char* name : {"cut.nii.gz", "cut.nii", "cut.mha", "cut.nrrd"}) {
    SCOPED_TRACE(name);
    const std::string path = file(name);
    write_volume(v, path);
    fs::resize_file(path, fs::file_size(path) / 2);
    expect_input_error([&] { read_volume(path); }, path, "truncated");
  }
  // .mhd keeps its voxels in a companion .raw file.
  write_volume(v, file("cut.mhd"));
  fs::resize_file(file("cut.raw"), fs::file_size(file("cut.raw")) - 4);
  expect_input_error([&] { read_volume(file("cut.mhd")); }, file("cut.mhd"), "truncated");
  // An uncompressed NRRD (write_volume compresses), cut inside its data.
  const std::string raw_nrrd = file("raw.nrrd");
  spit(raw_nrrd,
       "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nspacings: 1 1 1\nencoding: raw\n"
       "endian: little\n\n" +
           std::string(5 * sizeof(float), '\0'));
  expect_input_error([&] { read_volume(raw_nrrd); }, raw_nrrd, "truncated");
}

TEST_F(IoTest, NanVoxelIsInputError) {
  Volume v = make_volume(permuted_direction());
  v.at(2, 3, 1) = std::numeric_limits<float>::quiet_NaN();
  const std::string path = file("nan.mha");
  write_volume(v, path);
  expect_input_error([&] { read_volume(path); }, path, "non-finite voxel value at index (2, 3, 1)");
}

// A MetaImage written by hand, as write_volume cannot produce these.
void write_mha(const std::string& path, const std::string& spacing, int channels) {
  std::ofstream out(path, std::ios::binary);
  out << "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
      << "ElementSpacing = " << spacing << "\nDimSize = 2 2 2\n"
      << "ElementNumberOfChannels = " << channels << "\nElementType = MET_FLOAT\n"
      << "ElementDataFile = LOCAL\n";
  const std::vector<float> data(size_t(8 * channels), 1.0f);
  out.write(reinterpret_cast<const char*>(data.data()),
            std::streamsize(data.size() * sizeof(float)));
}

TEST_F(IoTest, ZeroSpacingIsInputError) {
  const std::string path = file("flat.mha");
  write_mha(path, "0 1 1", 1);
  expect_input_error([&] { read_volume(path); }, path, "spacing");
}

TEST_F(IoTest, VectorVolumeIsInputError) {
  const std::string path = file("vec.mha");
  write_mha(path, "1 1 1", 3);
  expect_input_error([&] { read_volume(path); }, path, "components");
}

TEST_F(IoTest, TwoDimensionalFileIsNotAVolume) {
  const std::string path = file("slice.nii.gz");
  write_float_image(Image(4, 3, 1.0f), path);
  expect_input_error([&] { read_volume(path); }, path, "2D");
}

TEST_F(IoTest, UnknownVolumeFormatIsInputError) {
  const std::string path = file("ct.xyz");
  spit(path, "this is not a volume");
  expect_input_error([&] { read_volume(path); }, path, "format");
}

// ---- images -------------------------------------------------------------------------------

TEST_F(IoTest, Png8And16BitKeepIntegerValuesTopRowFirst) {
  cv::Mat m8(3, 4, CV_8U), m16(3, 4, CV_16U);
  for (int v = 0; v < 3; ++v)
    for (int u = 0; u < 4; ++u) {
      m8.at<uint8_t>(v, u) = uint8_t(10 * v + u);
      m16.at<uint16_t>(v, u) = uint16_t(1000 * v + u + 40000 * (v == 2));
    }
  ASSERT_TRUE(cv::imwrite(file("a8.png"), m8));
  ASSERT_TRUE(cv::imwrite(file("a16.png"), m16));
  const Image a8 = read_image(file("a8.png")), a16 = read_image(file("a16.png"));
  ASSERT_EQ(a8.width, 4);
  ASSERT_EQ(a8.height, 3);
  ASSERT_EQ(a16.width, 4);
  for (int v = 0; v < 3; ++v)
    for (int u = 0; u < 4; ++u) {
      EXPECT_EQ(a8.at(u, v), float(m8.at<uint8_t>(v, u)));
      EXPECT_EQ(a16.at(u, v), float(m16.at<uint16_t>(v, u)));
    }
}

TEST_F(IoTest, ColourImageBecomesGrey) {
  std::vector<uint8_t> rgb = {200, 200, 200, 255, 0, 0};  // grey pixel, red pixel
  write_png_u8(rgb, 2, 1, 3, file("rgb.png"));
  const cv::Mat back = cv::imread(file("rgb.png"), cv::IMREAD_COLOR);
  EXPECT_EQ(back.at<cv::Vec3b>(0, 1), cv::Vec3b(0, 0, 255));  // stored as RGB, read as BGR
  const Image grey = read_image(file("rgb.png"));
  ASSERT_EQ(grey.width, 2);
  EXPECT_NEAR(grey.at(0, 0), 200.0f, 0.01f);
  EXPECT_NEAR(grey.at(1, 0), 0.299f * 255, 0.5f);
}

Image ramp_image(int w, int h) {
  Image img(w, h);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) img.at(u, v) = 0.1f * float(u) - 3.7f * float(v) + 1e-3f;
  return img;
}

TEST_F(IoTest, FloatImagesRoundTripExactly) {
  const Image img = ramp_image(5, 3);
  for (const char* name : {"d.tif", "d.tiff", "d.pfm", "d.nii", "d.nii.gz"}) {
    SCOPED_TRACE(name);
    ASSERT_TRUE(is_float_image_path(file(name)));
    write_float_image(img, file(name));
    const Image back = read_image(file(name));
    EXPECT_EQ(back.width, img.width);
    EXPECT_EQ(back.height, img.height);
    EXPECT_EQ(back.pixels, img.pixels);
  }
  EXPECT_FALSE(is_float_image_path("x.png"));
  expect_input_error([&] { write_float_image(img, file("d.png")); }, file("d.png"), "extension");
}

// 2D images in the volume formats: what `fluoro drr` writes as .mha and .nrrd (and ITK or RTK
// write), and a 3D file one slice thick, read as images with the volume reader's checks.
TEST_F(IoTest, TwoDimensionalMetaImageAndNrrdReadAsImages) {
  const Image img = ramp_image(5, 3);
  for (const char* name : {"d.mha", "d.nrrd"}) {
    SCOPED_TRACE(name);
    write_spaced_image(img, Eigen::Vector2d(0.3, 0.4), Eigen::Vector2d(1, 2), file(name));
    EXPECT_TRUE(is_2d_image_file(file(name)));
    const Image back = read_image(file(name));
    EXPECT_EQ(back.width, 5);
    EXPECT_EQ(back.height, 3);
    EXPECT_EQ(back.pixels, img.pixels);
    expect_input_error([&] { read_volume(file(name)); }, file(name), "2D");
  }
  write_float_image(img, file("d.nii"));
  EXPECT_TRUE(is_2d_image_file(file("d.nii")));
  const Volume planar = read_planar_volume(file("d.nii"));
  EXPECT_EQ(planar.geometry.size, Eigen::Vector3i(5, 3, 1));
  EXPECT_TRUE(std::equal(planar.voxels.begin(), planar.voxels.end(), img.pixels.begin(), img.pixels.end()));
  // A 2D MetaImage's direction is checked as a volume's is: parallel axes are refused.
  const std::string skew = file("skew.mha");
  spit(skew, "ObjectType = Image\nNDims = 2\nDimSize = 2 2\nElementType = MET_FLOAT\nTransformMatrix = 1 0 1 0\n"
             "ElementDataFile = LOCAL\n" + std::string(16, '\0'));
  expect_input_error([&] { read_image(skew); }, skew, "parallel");

  Volume slab;
  slab.geometry.size = Eigen::Vector3i(5, 3, 1);
  slab.voxels.assign(img.pixels.begin(), img.pixels.end());
  Volume thick;
  thick.geometry.size = Eigen::Vector3i(5, 3, 2);
  thick.voxels.resize(30, 1.0f);
  for (const char* name : {"slab.mha", "slab.nrrd", "slab.nii.gz"}) {
    SCOPED_TRACE(name);
    write_volume(slab, file(name));
    EXPECT_FALSE(is_2d_image_file(file(name)));  // a 3D header: `fluoro info` shows a volume
    EXPECT_EQ(read_image(file(name)).pixels, img.pixels);
    const std::string thick_name = file(std::string("thick_") + name);
    write_volume(thick, thick_name);
    expect_input_error([&] { read_image(thick_name); }, thick_name, "2 slices");
  }
  EXPECT_FALSE(is_2d_image_file(file("x.png")));

  // A short file is refused, not read with garbage pixels.
  const std::string cut = file("cut.mha");
  write_spaced_image(ramp_image(64, 64), Eigen::Vector2d(1, 1), Eigen::Vector2d::Zero(), cut);
  fs::resize_file(cut, fs::file_size(cut) - 100);
  expect_input_error([&] { read_image(cut); }, cut, "truncated");
}

TEST_F(IoTest, PfmRowOrderAgreesWithOpenCv) {
  const Image img = ramp_image(4, 3);
  write_float_image(img, file("r.pfm"));
  const cv::Mat m = cv::imread(file("r.pfm"), cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(m.empty());
  ASSERT_EQ(m.type(), CV_32F);
  for (int v = 0; v < 3; ++v)
    for (int u = 0; u < 4; ++u) EXPECT_EQ(m.at<float>(v, u), img.at(u, v));
}

TEST_F(IoTest, WritePngMapsWindowToBytes) {
  Image img(4, 1);
  img.pixels = {-5.0f, 0.0f, 5.0f, 20.0f};
  write_png(img, file("w.png"), 0.0f, 10.0f);
  const cv::Mat m = cv::imread(file("w.png"), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(m.type(), CV_8U);
  EXPECT_EQ(m.at<uint8_t>(0, 0), 0);
  EXPECT_EQ(m.at<uint8_t>(0, 1), 0);
  EXPECT_EQ(m.at<uint8_t>(0, 2), 128);
  EXPECT_EQ(m.at<uint8_t>(0, 3), 255);
  EXPECT_EQ(listing(), std::vector<std::string>{"w.png"});
}

template <class Pixel, unsigned Dim>
void write_dicom(const std::string& path, const itk::Size<Dim>& size) {
  using ItkImage = itk::Image<Pixel, Dim>;
  auto image = ItkImage::New();
  image->SetRegions(typename ItkImage::RegionType(size));
  image->Allocate();
  itk::EncapsulateMetaData<std::string>(image->GetMetaDataDictionary(), "0028|0004", "MONOCHROME2");
  for (size_t n = 0; n < image->GetLargestPossibleRegion().GetNumberOfPixels(); ++n)
    image->GetBufferPointer()[n] = Pixel(n);
  auto writer = itk::ImageFileWriter<ItkImage>::New();
  writer->SetImageIO(itk::GDCMImageIO::New());
  writer->SetFileName(path);
  writer->SetInput(image);
  writer->Update();
}

TEST_F(IoTest, SingleFrameDicomReads) {
  write_dicom<uint16_t, 2>(file("xray.dcm"), itk::Size<2>{{4, 3}});
  write_dicom<uint16_t, 3>(file("slice3d.dcm"), itk::Size<3>{{4, 3, 1}});
  for (const char* name : {"xray.dcm", "slice3d.dcm"}) {
    SCOPED_TRACE(name);
    const Image img = read_image(file(name));
    ASSERT_EQ(img.width, 4);
    ASSERT_EQ(img.height, 3);
    for (int v = 0; v < 3; ++v)
      for (int u = 0; u < 4; ++u) EXPECT_EQ(img.at(u, v), float(v * 4 + u));
  }
  // DICOM without the extension is recognised by content.
  fs::copy_file(file("xray.dcm"), file("IM0001"));
  EXPECT_EQ(read_image(file("IM0001")).pixels, read_image(file("xray.dcm")).pixels);
}

TEST_F(IoTest, MultiFrameDicomIsInputError) {
  const std::string path = file("cine.dcm");
  write_dicom<uint16_t, 3>(path, itk::Size<3>{{4, 3, 5}});
  expect_input_error([&] { read_image(path); }, path, "multi-frame");
}

TEST_F(IoTest, BadImagesAreInputErrors) {
  const std::string empty = file("empty.png");
  spit(empty, "");
  expect_input_error([&] { read_image(empty); }, empty, "empty");

  const std::string garbage = file("garbage.png");
  spit(garbage, "not a png at all");
  expect_input_error([&] { read_image(garbage); }, garbage, "cannot read");

  const std::string missing = file("missing.png");
  expect_input_error([&] { read_image(missing); }, missing, "not found");

  Image nan_image(3, 2, 1.0f);
  nan_image.at(2, 1) = std::numeric_limits<float>::quiet_NaN();
  write_float_image(nan_image, file("nan.tif"));
  expect_input_error([&] { read_image(file("nan.tif")); }, file("nan.tif"), "NaN");

  for (const char* name : {"cut.pfm", "cut.nii.gz", "cut.tif"}) {
    SCOPED_TRACE(name);
    const std::string cut = file(name);
    write_float_image(ramp_image(64, 64), cut);
    fs::resize_file(cut, fs::file_size(cut) / 2);
    expect_input_error([&] { read_image(cut); }, cut,
                       std::string(name) == "cut.tif" ? "cannot read" : "truncated");
  }
  cv::Mat big(64, 64, CV_16U);
  cv::randu(big, 0, 65535);
  const std::string cut_png = file("cut.png");
  ASSERT_TRUE(cv::imwrite(cut_png, big));
  fs::resize_file(cut_png, fs::file_size(cut_png) / 2);
  expect_input_error([&] { read_image(cut_png); }, cut_png, "cannot read");
}

// NIfTI-1 written by hand: int16 voxels with scl_slope/scl_inter, as CT exports often are. ITK
// reports such data as float; the truncation check must use the stored size.
TEST_F(IoTest, RescaledNiftiReadsHuAndIsNotMistakenForTruncated) {
  std::vector<char> bytes(352 + 2 * 2 * 2 * 2, 0);
  const auto put = [&](size_t at, auto value) {
    std::memcpy(bytes.data() + at, &value, sizeof value);
  };
  put(0, int32_t(348));
  const int16_t dim[8] = {3, 2, 2, 2, 1, 1, 1, 1};
  std::memcpy(bytes.data() + 40, dim, sizeof dim);
  put(70, int16_t(4));   // DT_INT16
  put(72, int16_t(16));  // bitpix
  const float pixdim[8] = {1, 0.5f, 0.5f, 2, 1, 1, 1, 1};
  std::memcpy(bytes.data() + 76, pixdim, sizeof pixdim);
  put(108, 352.0f);      // vox_offset
  put(112, 2.0f);        // scl_slope
  put(116, -1024.0f);    // scl_inter
  put(252, int16_t(1));  // qform_code: scanner, identity quaternion
  std::memcpy(bytes.data() + 344, "n+1", 4);
  for (int n = 0; n < 8; ++n) put(352 + 2 * size_t(n), int16_t(100 * n));
  const std::string path = file("hu.nii");
  spit(path, std::string(bytes.begin(), bytes.end()));

  const Volume v = read_volume(path);
  ASSERT_EQ(v.voxels.size(), 8u);
  for (int n = 0; n < 8; ++n) EXPECT_EQ(v.voxels[size_t(n)], 2.0f * float(100 * n) - 1024.0f);
  EXPECT_EQ(v.geometry.spacing, Eigen::Vector3d(0.5, 0.5, 2));

  fs::resize_file(path, fs::file_size(path) - 2);
  expect_input_error([&] { read_volume(path); }, path, "truncated");
}

// A .nii.gz of two gzip members (as bgzip writes them): its trailer gives the last member's length
// only, so the voxels are inflated into a growing buffer, and must read as ITK reads them; cut
// short, the same file is refused as truncated.
TEST_F(IoTest, MultiMemberGzipNiftiReadsAsItksReaderReadsIt) {
  const Volume like = make_volume(permuted_direction());
  write_typed_volume<int16_t>(file("plain.nii"), like);
  const std::string bytes = slurp(file("plain.nii"));
  const std::string path = file("members.nii.gz");
  for (const auto& [mode, part] : {std::pair{"wb", bytes.substr(0, 400)}, std::pair{"ab", bytes.substr(400)}}) {
    gzFile f = gzopen(path.c_str(), mode);
    ASSERT_TRUE(f);
    ASSERT_EQ(gzwrite(f, part.data(), unsigned(part.size())), int(part.size()));
    gzclose(f);
  }
  expect_same_volume(read_with_itk_reader(path), read_volume(path), 0.0);
  fs::resize_file(path, fs::file_size(path) - 40);
  expect_input_error([&] { read_volume(path); }, path, "truncated");
}

// Hand-made NIfTI-1 headers at the edges of ITK's rules, read as ITK's reader reads them: a slope
// of 0 (taken for 1) with an intercept (applied), and voxels from byte 348 (ITK's floor) on.
TEST_F(IoTest, NiftiEdgeHeadersReadAsItksReaderReadsThem) {
  struct Case {
    const char* name;
    float slope, intercept, vox_offset;
  };
  for (const Case& c : {Case{"slope0_intercept.nii", 0.0f, -1024.0f, 352.0f}, Case{"offset348.nii", 1.0f, 0.0f, 348.0f},
                        Case{"offset0.nii", 0.0f, 0.0f, 0.0f}, Case{"offset400.nii", 1.0f, 0.0f, 400.0f}}) {
    SCOPED_TRACE(c.name);
    const size_t data_at = std::max<size_t>(348, size_t(c.vox_offset));
    // (4 bytes more than the voxels: the header check counts a single file's voxels from byte 352.)
    std::vector<char> bytes(data_at + 2 * 2 * 2 * 2 + 4, 0);
    const auto put = [&](size_t at, auto value) { std::memcpy(bytes.data() + at, &value, sizeof value); };
    put(0, int32_t(348));
    const int16_t dim[8] = {3, 2, 2, 2, 1, 1, 1, 1};
    std::memcpy(bytes.data() + 40, dim, sizeof dim);
    put(70, int16_t(4));  // DT_INT16
    put(72, int16_t(16));
    const float pixdim[8] = {1, 1, 1, 1, 1, 1, 1, 1};
    std::memcpy(bytes.data() + 76, pixdim, sizeof pixdim);
    put(108, c.vox_offset);
    put(112, c.slope);
    put(116, c.intercept);
    put(252, int16_t(1));
    std::memcpy(bytes.data() + 344, "n+1", 4);
    for (int n = 0; n < 8; ++n) put(data_at + 2 * size_t(n), int16_t(100 * n + 7));
    const std::string path = file(c.name);
    spit(path, std::string(bytes.begin(), bytes.end()));
    const Volume itk = read_with_itk_reader(path);
    EXPECT_EQ(itk.voxels[1], 107.0f + c.intercept);  // ITK: slope 0 is 1, data from byte 348 at the earliest
    expect_same_volume(itk, read_volume(path), 0.0);
  }
}

// ---- JSON ---------------------------------------------------------------------------------

PinholeCamera test_camera() {
  PinholeCamera c = PinholeCamera::look_at({10, -900, 30}, {0, 0, 0}, {0, 0, -1}, 1200.5, 640, 480);
  c.K(0, 1) = 0.25;
  c.pixel_spacing_mm = Eigen::Vector2d(0.3, 0.31);
  return c;
}

// Hand-made MetaImages at the edges of what read_volume reads itself: each is read as ITK's reader
// reads it (the forms it leaves to ITK too: big-endian data, MET_LONG, a HeaderSize), and a
// compressed stream that is corrupt or holds too few voxels is refused, where MetaIO would print
// "Uncompress failed" or leave voxels uninitialised.
TEST_F(IoTest, MetaImageEdgeHeadersReadAsItksReaderReadsThem) {
  std::vector<int16_t> voxels(2 * 3 * 4);
  for (size_t i = 0; i < voxels.size(); ++i) voxels[i] = int16_t(int(i * 37 % 101) - 50);
  const std::string little(reinterpret_cast<const char*>(voxels.data()), voxels.size() * 2);
  std::string big = little;
  for (size_t i = 0; i < big.size(); i += 2) std::swap(big[i], big[i + 1]);
  const auto compressed = [](const std::string& data) {
    uLongf size = compressBound(uLong(data.size()));
    std::string out(size, '\0');
    EXPECT_EQ(compress2(reinterpret_cast<Bytef*>(out.data()), &size, reinterpret_cast<const Bytef*>(data.data()),
                        uLong(data.size()), 6),
              Z_OK);
    out.resize(size);
    return out;
  };
  const auto header = [](const std::string& type, const std::string& extra, const std::string& data_file) {
    return "ObjectType = Image\nNDims = 3\nBinaryData = True\n" + extra +
           "TransformMatrix = 0 1 0 1 0 0 0 0 1\nOffset = -3 4.5 7\nElementSpacing = 0.5 1.5 2\n"
           "DimSize = 2 3 4\nElementType = " + type + "\nElementDataFile = " + data_file + "\n";
  };
  const auto compressed_keys = [](const std::string& stream) {
    return "CompressedData = True\nCompressedDataSize = " + std::to_string(stream.size()) + "\n";
  };
  struct Case {
    const char* name;
    std::string text;
    bool ours;  // read by the project's reader, not left to ITK's
  };
  const std::string z = compressed(little);
  std::string int32_data;
  for (const int16_t v : voxels) {
    const int32_t w = int32_t(v) * 70000;
    int32_data.append(reinterpret_cast<const char*>(&w), 4);
  }
  for (const Case& c : {
           Case{"raw.mha", header("MET_SHORT", "BinaryDataByteOrderMSB = False\n", "LOCAL") + little, true},
           Case{"local_spelling.mha", header("MET_SHORT", "", "Local") + little, true},
           Case{"zlib.mha", header("MET_SHORT", compressed_keys(z), "LOCAL") + z, true},
           Case{"crlf.mha", std::regex_replace(header("MET_SHORT", "", "LOCAL"), std::regex("\n"), "\r\n") + little,
                true},
           Case{"big_endian.mha", header("MET_SHORT", "BinaryDataByteOrderMSB = True\n", "LOCAL") + big, false},
           Case{"met_long.mha", header("MET_LONG", "", "LOCAL") + int32_data, false},
           Case{"header_size.mha", header("MET_SHORT", "HeaderSize = 0\n", "LOCAL") + little, false},
       }) {
    SCOPED_TRACE(c.name);
    const std::string path = file(c.name);
    spit(path, c.text);
    EXPECT_EQ(bool(check_metaimage_header_for_voxels(path)), c.ours);
    const Volume ours = read_volume(path);
    expect_same_volume(read_with_itk_reader(path), ours, 0.0);
    EXPECT_EQ(ours.voxels[5], float(c.name == std::string("met_long.mha") ? voxels[5] * 70000 : voxels[5]));
  }
  // A stream of fewer voxels than DimSize describes, and a corrupt one (its deflate data mangled).
  const std::string half = compressed(little.substr(0, little.size() / 2));
  const std::string few = file("few.mha");
  spit(few, header("MET_SHORT", compressed_keys(half), "LOCAL") + half);
  expect_input_error([&] { read_volume(few); }, few, "compressed voxel data hold 24 of the 48 bytes");
  std::string mangled = z;
  for (size_t i = 2; i < mangled.size() - 4; ++i) mangled[i] = char(0xff);
  const std::string corrupt = file("corrupt.mha");
  spit(corrupt, header("MET_SHORT", compressed_keys(mangled), "LOCAL") + mangled);
  expect_input_error([&] { read_volume(corrupt); }, corrupt, "corrupt compressed voxel data");
  // A flag MetaIO would read as false ("\rTrue" starts with '\r'), and more voxels than the
  // compressed bytes can inflate to (refused before they are allocated).
  const std::string cr = file("cr.mha");
  const std::string flag = "BinaryData = ";
  std::string cr_header = header("MET_SHORT", "", "LOCAL");
  cr_header.insert(cr_header.find(flag) + flag.size(), "\r");
  spit(cr, cr_header + little);
  expect_input_error([&] { read_volume(cr); }, cr, "starts with a carriage return");
  const std::string huge = file("huge.mhd");  // (a .mhd's size is not checked against its file)
  std::string claim = header("MET_SHORT", compressed_keys(z), "LOCAL") + z;
  claim.replace(claim.find("DimSize = 2 3 4"), 15, "DimSize = 2000 3000 4000");
  spit(huge, claim);
  expect_input_error([&] { read_volume(huge); }, huge, "bytes of compressed data can hold");
}

// ElementDataFile = LIST: the slice files named after the header, one a line. A valid list reads as
// ITK's reader reads it; what MetaIO would crash on (an empty line: fuzz_volume_mha) or read as
// garbage (too few lines, a missing or short slice file) is refused.
TEST_F(IoTest, MetaImageSliceListsAreCheckedBeforeMetaIOReadsThem) {
  std::vector<std::string> names;
  for (int k = 0; k < 4; ++k) {
    std::string slice;
    for (int i = 0; i < 6; ++i) {
      const int16_t v = int16_t(100 * k + 7 * i - 20);
      slice.append(reinterpret_cast<const char*>(&v), 2);
    }
    names.push_back("slice" + std::to_string(k) + ".raw");
    spit(file(names.back()), slice);
  }
  const auto header = [](const std::string& list) {
    return "ObjectType = Image\nNDims = 3\nBinaryData = True\nElementSpacing = 1 1 2\nDimSize = 2 3 4\n"
           "ElementType = MET_SHORT\nElementDataFile = " + list + "\n";
  };
  const std::string lines = names[0] + "\n" + names[1] + "\n" + names[2] + "\n" + names[3] + "\n";
  const std::string good = file("list.mhd");
  spit(good, header("LIST") + lines);
  expect_same_volume(read_with_itk_reader(good), read_volume(good), 0.0);
  EXPECT_EQ(read_volume(good).at(1, 2, 3), 100.0f * 3 + 7 * 5 - 20);
  for (const char* list : {"LIST 2", "LIST 2D"}) {  // the slices' dimension stated (MetaIO's form: 2D)
    spit(good, header(list) + lines);
    EXPECT_EQ(read_volume(good).at(1, 2, 3), 100.0f * 3 + 7 * 5 - 20) << list;
  }

  struct Case {
    const char* name;
    std::string text;
    const char* problem;
  };
  for (const Case& c : {
           Case{"empty_line.mhd", header("LIST") + names[0] + "\n\n" + names[2] + "\n" + names[3] + "\n",
                "an empty line in the LIST"},
           Case{"few_lines.mhd", header("LIST") + names[0] + "\n" + names[1] + "\n", "names 2 of the 4 slice files"},
           Case{"unended_line.mhd", header("LIST") + names[0] + "\n" + names[1] + "\n" + names[2] + "\n" + names[3],
                "names 3 of the 4 slice files"},
           Case{"missing.mhd", header("LIST") + names[0] + "\nnone.raw\n" + names[2] + "\n" + names[3] + "\n",
                "none.raw not found"},
           Case{"negative_dim.mhd", header("LIST -1") + lines, "LIST dimension"},
           Case{"compressed.mhd", "CompressedData = True\nCompressedDataSize = 9\n" + header("LIST") + lines,
                "compressed data in a LIST"},
       }) {
    SCOPED_TRACE(c.name);
    spit(file(c.name), c.text);
    expect_input_error([&] { read_volume(file(c.name)); }, file(c.name), c.problem);
  }
  fs::resize_file(file(names[1]), 10);
  expect_input_error([&] { read_volume(good); }, good, "truncated (10 of the 12 bytes");
}

TEST_F(IoTest, CameraRoundTrips) {
  const PinholeCamera c = test_camera();
  write_camera(c, file("cam.json"));
  const PinholeCamera back = read_camera(file("cam.json"));
  EXPECT_EQ(back.width, 640);
  EXPECT_EQ(back.height, 480);
  EXPECT_EQ(back.K, c.K);
  EXPECT_EQ(back.R, c.R);
  EXPECT_EQ(back.t, c.t);
  ASSERT_TRUE(back.pixel_spacing_mm.has_value());
  EXPECT_EQ(*back.pixel_spacing_mm, *c.pixel_spacing_mm);

  PinholeCamera plain = c;
  plain.pixel_spacing_mm.reset();
  const nlohmann::json j = camera_to_json(plain);
  EXPECT_FALSE(j.contains("pixel_spacing_mm"));
  write_json(j, file("plain.json"));
  EXPECT_FALSE(read_camera(file("plain.json")).pixel_spacing_mm.has_value());
}

TEST_F(IoTest, CameraFromProjectionMatrix) {
  const PinholeCamera c = test_camera();
  const Eigen::Matrix<double, 3, 4> P = c.projection_matrix();
  nlohmann::json j = {{"width", 640}, {"height", 480.0}, {"P", nlohmann::json::array()}};
  for (int r = 0; r < 3; ++r) j["P"].push_back({P(r, 0), P(r, 1), P(r, 2), P(r, 3)});
  write_json(j, file("p.json"));
  const PinholeCamera back = read_camera(file("p.json"));
  EXPECT_TRUE(back.K.isApprox(c.K, 1e-9)) << back.K;
  EXPECT_TRUE(back.R.isApprox(c.R, 1e-9)) << back.R;
  EXPECT_TRUE(back.t.isApprox(c.t, 1e-9)) << back.t.transpose();
}

// A P given at any scale (here 2.5) decomposes to the same K, R and t.
TEST_F(IoTest, CameraFromScaledProjectionMatrix) {
  const PinholeCamera c = test_camera();
  const Eigen::Matrix<double, 3, 4> P = 2.5 * c.projection_matrix();
  nlohmann::json j = {{"width", 640}, {"height", 480}, {"P", nlohmann::json::array()}};
  for (int r = 0; r < 3; ++r) j["P"].push_back({P(r, 0), P(r, 1), P(r, 2), P(r, 3)});
  write_json(j, file("p.json"));
  const PinholeCamera back = read_camera(file("p.json"));
  EXPECT_TRUE(back.K.isApprox(c.K, 1e-9)) << back.K;
  EXPECT_TRUE(back.R.isApprox(c.R, 1e-9)) << back.R;
  EXPECT_TRUE(back.t.isApprox(c.t, 1e-9)) << back.t.transpose();
}

// Writes the test camera with one field replaced and expects read_camera to name the problem.
void expect_bad_camera(const std::string& path, const char* key, const nlohmann::json& value,
                       const std::string& word) {
  nlohmann::json j = camera_to_json(test_camera());
  if (value.is_null())
    j.erase(key);
  else
    j[key] = value;
  write_json(j, path);
  expect_input_error([&] { read_camera(path); }, path, word);
}

TEST_F(IoTest, BadCamerasAreInputErrors) {
  const std::string path = file("bad.json");
  expect_bad_camera(path, "K", {{0, 0, 320}, {0, 1000, 240}, {0, 0, 1}}, "singular");
  expect_bad_camera(path, "R", {{1, 0, 0}, {0, 1, 0}, {0, 0, -1}}, "improper");
  expect_bad_camera(path, "K", {{1000, 0, 320}, {0, 1000, 240}},
                    "K must be a 3x3 array of numbers");
  expect_bad_camera(path, "K", {{1000, 0, 320}, {0, "1000", 240}, {0, 0, 1}}, "K must be a 3x3");
  expect_bad_camera(path, "t", {1, 2}, "t must be an array of 3 numbers");
  expect_bad_camera(path, "width", 0, "width must be a positive integer");
  expect_bad_camera(path, "height", 480.5, "height must be a positive integer");
  expect_bad_camera(path, "R", nullptr, "missing key \"R\"");
  expect_bad_camera(path, "pixel_spacing_mm", {0.3}, "pixel_spacing_mm");

  const std::string missing = file("missing.json");
  expect_input_error([&] { read_camera(missing); }, missing, "not found");

  const std::string broken = file("broken.json");
  spit(broken, "{\"width\": 640,\n \"height\": }");
  expect_input_error([&] { read_camera(broken); }, broken, "invalid JSON at byte");

  const std::string array = file("array.json");
  spit(array, "[1, 2, 3]");
  expect_input_error([&] { read_camera(array); }, array, "object");
}

TEST_F(IoTest, PoseRoundTripsAndRejectsImproper) {
  const Pose p = pose_from_rotation_vector({0.1, -0.2, 0.3}, {5, -6, 700.25});
  write_pose(p, file("pose.json"));
  EXPECT_EQ(read_pose(file("pose.json")).matrix(), p.matrix());

  Eigen::Matrix4d m = p.matrix();
  m.col(0) *= -1;
  write_json({{"T_world_ct",
               {{m(0, 0), m(0, 1), m(0, 2), m(0, 3)},
                {m(1, 0), m(1, 1), m(1, 2), m(1, 3)},
                {m(2, 0), m(2, 1), m(2, 2), m(2, 3)},
                {0, 0, 0, 1}}}},
             file("flip.json"));
  expect_input_error([&] { read_pose(file("flip.json")); }, file("flip.json"), "improper");

  write_json({{"T_world_ct", {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}}}, file("small.json"));
  expect_input_error([&] { read_pose(file("small.json")); }, file("small.json"), "4x4");
}

}  // namespace
}  // namespace fluoro
