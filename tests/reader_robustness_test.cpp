// Mutated volume and image files that used to crash the program, print library lines or pass as
// valid (issue 15; scripts/reader_robustness.py found them): each must now be an InputError whose
// one-line message names the file and the problem, and the program must print exactly that line.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "engine/error.hpp"
#include "engine/image_io.hpp"
#include "engine/volume_io.hpp"
#include "tests/cli_fixture.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

class ReaderRobustness : public test::CliTest {
 protected:
  std::vector<char> bytes(const std::string& name) const {
    std::ifstream in(path(name), std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }
  void put(const std::string& name, const std::vector<char>& data) const {
    std::ofstream(path(name), std::ios::binary).write(data.data(), std::streamsize(data.size()));
  }
  template <class T>
  static void poke(std::vector<char>& data, size_t offset, T value) {
    std::memcpy(&data[offset], &value, sizeof value);
  }
  // A valid 4^3 float NIfTI-1 (as ITK writes it), returned as bytes to be mutated.
  std::vector<char> nifti() const {
    Volume v;
    v.geometry.size = {4, 4, 4};
    v.geometry.spacing = {1.5, 1.5, 2.0};
    v.voxels.assign(64, 100.0f);
    write_volume(v, path("valid.nii"));
    return bytes("valid.nii");
  }
  // A MetaImage of 4^3 floats with the given extra header lines before ElementDataFile.
  void metaimage(const std::string& name, const std::string& lines, const std::string& type = "MET_FLOAT") const {
    std::ofstream f(path(name), std::ios::binary);
    f << "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = " << type << "\n" << lines
      << "ElementDataFile = LOCAL\n";
    const float value = 7.0f;
    for (int i = 0; i < 64; ++i) f.write(reinterpret_cast<const char*>(&value), sizeof value);
  }
  // read_volume throws an InputError naming the file with `word` in it, and `fluoro info` prints
  // just that line and exits with 2.
  void expect_refused(const std::string& name, const std::string& word) const {
    try {
      read_volume(path(name));
      ADD_FAILURE() << name << " was read";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(word), std::string::npos) << e.what();
    }
    expect_bad_input(run("info " + path(name)), name);
  }
};

constexpr size_t kSformCode = 254, kSrowX = 280, kDim = 40, kDatatype = 70;

TEST_F(ReaderRobustness, AValidNiftiStillReads) {
  put("ok.nii", nifti());
  const Volume v = read_volume(path("ok.nii"));
  EXPECT_EQ(v.geometry.size.x(), 4);
  EXPECT_DOUBLE_EQ(v.geometry.spacing.z(), 2.0);
  EXPECT_EQ(v.voxels[10], 100.0f);
}

TEST_F(ReaderRobustness, NanInTheNiftiSformIsRefusedNotAnAbort) {
  // Before: VNL's "matrix has non-finite elements" and SIGABRT.
  std::vector<char> b = nifti();
  poke<int16_t>(b, kSformCode, 1);
  poke<float>(b, kSrowX, std::numeric_limits<float>::quiet_NaN());
  put("nan_sform.nii", b);
  expect_refused("nan_sform.nii", "sform");
  poke<float>(b, kSrowX, 1.0f);
  poke<float>(b, kSrowX + 12, std::numeric_limits<float>::infinity());  // the x offset
  put("inf_offset.nii", b);
  expect_refused("inf_offset.nii", "sform offset");
}

TEST_F(ReaderRobustness, AHugeOrSubnormalSformIsRefused) {
  // Before: a 1.7e38 entry kept ITK's SVD busy past a minute; a subnormal one made it print
  // "suspicious return value (3) from SVDC" and read the file anyway.
  std::vector<char> b = nifti();
  poke<int16_t>(b, kSformCode, 1);
  poke<float>(b, kSrowX + 4, -1.7e38f);
  put("huge.nii", b);
  expect_refused("huge.nii", "sform column 1");
  poke<float>(b, kSrowX + 4, 3.6e-43f);
  put("subnormal.nii", b);
  expect_refused("subnormal.nii", "subnormal");
}

TEST_F(ReaderRobustness, BadNiftiDimensionsAndDatatypesAreOneLine) {
  // Before: the NIfTI library's "** ERROR: nifti_convert_nhdr2nim: bad dim[1]" line, then ours.
  std::vector<char> b = nifti();
  poke<int16_t>(b, kDim + 2, -1);
  put("dim.nii", b);
  expect_refused("dim.nii", "dim[1] is -1");
  b = nifti();
  poke<int16_t>(b, kDatatype, 99);
  put("datatype.nii", b);
  expect_refused("datatype.nii", "datatype 99");
}

TEST_F(ReaderRobustness, AnUnknownMetaImageElementTypeIsBadInputNotInternal) {
  // Before: exit 1, "internal error: ... Unknown component type".
  metaimage("none.mha", "", "MET_NONE");
  expect_refused("none.mha", "ElementType MET_NONE");
}

TEST_F(ReaderRobustness, MetaImageHeaderProblemsAreOneLine) {
  // Before: MetaIO's "DimSize required and not defined." and three more lines.
  {
    std::ofstream f(path("nodim.mha"));
    f << "ObjectType = Image\nNDims = 3\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n";
  }
  expect_refused("nodim.mha", "no DimSize");
  metaimage("nan.mha", "TransformMatrix = nan 0 0 0 1 0 0 0 1\n");
  expect_refused("nan.mha", "TransformMatrix");
  metaimage("flat.mha", "TransformMatrix = 1 0 0 1 0 0 0 0 1\n");
  expect_refused("flat.mha", "parallel");
  metaimage("spacing.mha", "ElementSpacing = 1 -2 1\n");
  expect_refused("spacing.mha", "spacing");
}

TEST_F(ReaderRobustness, RawDataCalledCompressedIsRefusedNotReadAsGarbage) {
  // Before: MetaIO printed "Uncompress failed" and the program went on with exit 0.
  metaimage("raw.mha", "CompressedData = True\nCompressedDataSize = 256\n");
  expect_refused("raw.mha", "Uncompress failed");
}

TEST_F(ReaderRobustness, CorruptPngsAreOneLineNotAnAbort) {
  std::vector<uint8_t> grey(32 * 32);
  for (size_t i = 0; i < grey.size(); ++i) grey[i] = uint8_t(i * 7);
  write_png_u8(grey, 32, 32, 1, path("ok.png"));
  EXPECT_EQ(read_image(path("ok.png")).at(3, 0), float(uint8_t(21)));

  // Before: libpng's "IHDR: CRC error" line and SIGABRT (ITK's reader set no jump buffer).
  std::vector<char> b = bytes("ok.png");
  b[18] = char(0x7f);  // the width's third byte: the IHDR chunk no longer matches its CRC
  put("crc.png", b);
  expect_bad_input(run("info " + path("crc.png")), "crc.png");

  // Before: libpng's own "Read Error" line, then ours.
  b = bytes("ok.png");
  b.resize(b.size() - 30);
  put("cut.png", b);
  const test::CliResult r = run("info " + path("cut.png"));
  expect_bad_input(r, "cut.png");
  EXPECT_NE(r.err.find("truncated"), std::string::npos) << r.err;
}

TEST_F(ReaderRobustness, LibtiffWarningsAreNotPrinted) {
  // A fuzzed TIFF (fuzz_image_tif) with a bogus StripByteCounts tag: before, libtiff's own
  // "TIFFReadDirectory: Warning, Bogus ..." line came before the program's.
  fs::copy_file(fs::path(FLUORO_SOURCE_DIR) / "tests/fuzz_regressions/image_tif/bogus_strip_byte_counts",
                path("bogus.tif"));
  expect_bad_input(run("info " + path("bogus.tif")), "bogus.tif");
  // The DateTime tag ITK's TIFF reader copied past its end (AddressSanitizer: heap-buffer-overflow).
  fs::copy_file(fs::path(FLUORO_SOURCE_DIR) / "tests/fuzz_regressions/image_tif/datetime_15_bytes",
                path("datetime.tif"));
  const test::CliResult r = run("info " + path("datetime.tif"));
  expect_bad_input(r, "datetime.tif");
  EXPECT_NE(r.err.find("DateTime"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace fluoro
