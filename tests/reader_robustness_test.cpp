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

namespace fluoro {
namespace {

// read_volume refuses the file with an InputError naming it and holding `word` (no program run).
void expect_read_refused(const std::string& file, const std::string& word) {
  try {
    read_volume(file);
    ADD_FAILURE() << file << " was read";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(file + ": ", 0), 0u) << what;
    EXPECT_NE(what.find(word), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
}

// MetaIO's header parser (MET_Read) takes a key up to '=', ':' or the line's end, skips to the
// next '=' or ':' across lines, reads numbers with >> across lines, and sizes its arrays by NDims
// as read so far: a negative NDims before DimSize had it read 2^64 numbers (a hang; fuzz_volume_mha).
TEST_F(ReaderRobustness, MetaImageHeadersAreCheckedAsMetaIOSplitsThem) {
  // The fuzzer's input: "NDims == -120 -120 -120" before CenterOfRotation, a second NDims later.
  fs::copy_file(fs::path(FLUORO_SOURCE_DIR) / "tests/fuzz_regressions/volume_mha/metaio_read_never_ends", path("hang.mha"));
  expect_refused("hang.mha", "line 2: NDims must be 1 number");
  const auto header = [this](const std::string& name, const std::string& text) {
    std::ofstream f(path(name), std::ios::binary);
    f << text << "ElementDataFile = LOCAL\n";
    const float value = 7.0f;
    for (int i = 0; i < 64; ++i) f.write(reinterpret_cast<const char*>(&value), sizeof value);
  };
  header("negative.mha", "NDims = -2\nDimSize = 4 4 4\nElementType = MET_FLOAT\n");
  expect_read_refused(path("negative.mha"), "NDims must be an integer from 1 to 10, is \"-2\"");
  header("twice.mha", "NDims = 3\nDimSize = 4 4 4\nNDims = 3\nElementType = MET_FLOAT\n");
  expect_read_refused(path("twice.mha"), "line 3: NDims is given twice");
  header("early.mha", "DimSize = 4 4 4\nNDims = 3\nElementType = MET_FLOAT\n");
  expect_read_refused(path("early.mha"), "line 1: DimSize before NDims");
  // A line without a separator takes the next line's value in MetaIO: "BinaryData" would be
  // "MET_FLOAT" and ElementType missing.
  header("nosep.mha", "NDims = 3\nDimSize = 4 4 4\nBinaryData\nElementType = MET_FLOAT\n");
  expect_read_refused(path("nosep.mha"), "line 3: no '=' after \"BinaryData\"");
  // >> carries on to the next line for the third size, and would not read hexadecimal.
  header("split.mha", "NDims = 3\nDimSize = 4 4\n4\nElementType = MET_FLOAT\n");
  expect_read_refused(path("split.mha"), "DimSize must be 3 numbers, is \"4 4\"");
  header("hex.mha", "NDims = 3\nDimSize = 0x4 4 4\nElementType = MET_FLOAT\n");
  expect_read_refused(path("hex.mha"), "DimSize must be 3 numbers");
  // MetaIO inflates only CompressedDataSize bytes and leaves the voxels past them as they were:
  // a smaller size than the stream's is refused (it read as exit 0 with uninitialised voxels).
  Volume small;
  small.geometry.size = {4, 4, 4};
  small.voxels.assign(64, 5.0f);
  write_volume(small, path("packed.mha"));  // compressed, with its CompressedDataSize
  EXPECT_EQ(read_volume(path("packed.mha")).voxels[63], 5.0f);
  std::vector<char> packed = bytes("packed.mha");
  std::string text(packed.begin(), packed.end());
  const size_t at = text.find("CompressedDataSize = ");
  ASSERT_NE(at, std::string::npos);
  const size_t eol = text.find('\n', at);
  const std::string stream_bytes = text.substr(at + 21, eol - at - 21);
  text.replace(at, eol - at, "CompressedDataSize = 1" + std::string(stream_bytes.size() - 1, ' '));  // same length
  put("short_size.mha", std::vector<char>(text.begin(), text.end()));
  expect_read_refused(path("short_size.mha"), "CompressedDataSize is 1 but " + stream_bytes + " bytes of compressed data follow");
  // ':' separates as '=' does, and runs of separators are skipped, as MetaIO reads them.
  header("colon.mha", "NDims: 3\nDimSize := 4 4 4\nElementSpacing = 1 1 2.5\nElementType = MET_FLOAT\n");
  const Volume v = read_volume(path("colon.mha"));
  EXPECT_EQ(v.geometry.size.z(), 4);
  EXPECT_DOUBLE_EQ(v.geometry.spacing.z(), 2.5);
  EXPECT_EQ(v.voxels[63], 7.0f);
}

// NRRD headers are checked against the data they come with before ITK allocates the voxels; a
// file named .nrrd is read as NRRD only (the other formats' probes spent 25 s and 1.8 GB on a
// fuzzed one, tests/fuzz_regressions/volume_nrrd/sizes_beyond_file).
TEST_F(ReaderRobustness, NrrdSizesAreCheckedAgainstTheData) {
  const std::string head = "NRRD0004\ntype: float\ndimension: 3\nspacings: 1 1 1\nendian: little\n";
  const auto put_text = [this](const std::string& name, const std::string& text) {
    std::ofstream(path(name), std::ios::binary) << text;
  };
  put_text("big.nrrd", head + "sizes: 2000 2000 2000\nencoding: raw\n\n0123456789");
  expect_refused("big.nrrd", "file truncated (10 data bytes; the header's sizes, type and raw encoding need at least 32000000000)");
  put_text("big.nhdr", head + "sizes: 2000 2000 2000\nencoding: raw\ndata file: big.raw\n");
  put_text("big.raw", std::string(1000, '\0'));
  expect_read_refused(path("big.nhdr"), "file truncated (1000 data bytes");
  put_text("missing.nhdr", head + "sizes: 2 2 2\nencoding: raw\ndata file: nowhere.raw\n");
  expect_read_refused(path("missing.nhdr"), "data file " + path("nowhere.raw") + " not found");
  // 1 MiB of floats cannot come out of 100 bytes of deflate (at most 1032:1).
  put_text("gz.nrrd", head + "sizes: 64 64 64\nencoding: gzip\n\n" + std::string(100, 'x'));
  expect_read_refused(path("gz.nrrd"), "need at least 1017");
  put_text("bz.nrrd", head + "sizes: 2 2 2\nencoding: bzip2\n\n" + std::string(100, 'x'));
  expect_read_refused(path("bz.nrrd"), "bzip2 encoding");
  put_text("notnrrd.nrrd", "NRR&0004\ntype: float\n");
  expect_read_refused(path("notnrrd.nrrd"), "not a NRRD file");
  put_text("type.nrrd", "NRRD0004\ntype: block\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n");
  expect_read_refused(path("type.nrrd"), "unsupported type \"block\"");
  // A valid attached and detached NRRD still read, the detached one's data in its own file.
  std::string data(32, '\0');
  const float value = 3.5f;
  for (int i = 0; i < 8; ++i) std::memcpy(&data[size_t(i) * 4], &value, 4);
  put_text("ok.nrrd", head + "sizes: 2 2 2\nencoding: raw\n\n" + data);
  EXPECT_EQ(read_volume(path("ok.nrrd")).voxels[7], 3.5f);
  put_text("ok.raw", data);
  put_text("ok.nhdr", head + "sizes: 2 2 2\nencoding: raw\ndata file: ok.raw\n");
  EXPECT_EQ(read_volume(path("ok.nhdr")).voxels[7], 3.5f);
  // "data file: LIST": the header's remaining lines are the data files (here one 3D chunk).
  put_text("list.nhdr", head + "sizes: 2 2 2\nencoding: raw\ndata file: LIST 3\nok.raw\n");
  EXPECT_EQ(read_volume(path("list.nhdr")).voxels[7], 3.5f);
}

}  // namespace
}  // namespace fluoro
