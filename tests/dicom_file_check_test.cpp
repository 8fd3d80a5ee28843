// DICOM files are checked before GDCM reads them (engine/dicom_file_check.hpp): a corrupt element
// length made GDCM zero-fill 1.8 GB for 8.6 s before its refusal. Real files, as ITK and GDCM write
// them, still read; corrupt ones are refused in one line naming the file, by the library and by
// the program (exit 2).
#include <gtest/gtest.h>

#include <itkGDCMImageIO.h>
#include <itkImage.h>
#include <itkImageFileWriter.h>
#include <itkMetaDataObject.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "engine/error.hpp"
#include "engine/image_io.hpp"
#include "engine/volume_io.hpp"
#include "tests/cli_fixture.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

class DicomFileCheck : public test::CliTest {
 protected:
  // A 4 x 3 x 5 multi-frame volume of 16-bit voxels 0, 1, 2, ... as ITK's GDCM writer writes it.
  std::vector<char> written_by_gdcm() const {
    using Short3 = itk::Image<uint16_t, 3>;
    auto image = Short3::New();
    image->SetRegions(Short3::RegionType(itk::Size<3>{{4, 3, 5}}));
    image->Allocate();
    itk::EncapsulateMetaData<std::string>(image->GetMetaDataDictionary(), "0028|0004", "MONOCHROME2");
    for (size_t n = 0; n < 60; ++n) image->GetBufferPointer()[n] = uint16_t(n);
    auto writer = itk::ImageFileWriter<Short3>::New();
    writer->SetImageIO(itk::GDCMImageIO::New());
    writer->SetFileName(path("gdcm.dcm"));
    writer->SetInput(image);
    writer->Update();
    std::ifstream in(path("gdcm.dcm"), std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }
  void put(const std::string& name, const std::vector<char>& data) const {
    std::ofstream(path(name), std::ios::binary).write(data.data(), std::streamsize(data.size()));
  }
  // An element of the written file, in whichever VR encoding GDCM chose (ITK writes implicit VR
  // little endian): where its tag, its length field (2 or 4 bytes) and its value are.
  struct Found {
    size_t tag = 0, length_at = 0, length_bytes = 0, value_at = 0;
    bool explicit_vr = false;
  };
  static Found find_element(const std::vector<char>& data, uint16_t group, uint16_t element, const char* vr) {
    const char tag[4] = {char(group & 0xFF), char(group >> 8), char(element & 0xFF), char(element >> 8)};
    const auto it = group == 0x7FE0 ? std::find_end(data.begin() + 132, data.end(), tag, tag + 4)
                                    : std::search(data.begin() + 132, data.end(), tag, tag + 4);
    Found f;
    EXPECT_NE(it, data.end()) << "no element " << group << "," << element;
    if (it == data.end()) return f;
    f.tag = size_t(it - data.begin());
    f.explicit_vr = data[f.tag + 4] == vr[0] && data[f.tag + 5] == vr[1];
    const bool long_vr = std::string(vr) == "OW" || std::string(vr) == "OB";
    if (!f.explicit_vr) f = {f.tag, f.tag + 4, 4, f.tag + 8, false};
    else if (long_vr) f = {f.tag, f.tag + 8, 4, f.tag + 12, true};
    else f = {f.tag, f.tag + 6, 2, f.tag + 8, true};
    return f;
  }
  // read_volume and read_image refuse the file with `word` in a message naming it, and `fluoro
  // info` prints that one line and exits with 2.
  void expect_refused(const std::string& name, const std::string& word) const {
    for (const bool volume : {true, false}) {
      SCOPED_TRACE(volume ? "read_volume" : "read_image");
      try {
        if (volume)
          read_volume(path(name));
        else
          read_image(path(name));
        ADD_FAILURE() << name << " was read";
      } catch (const InputError& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find(path(name)), std::string::npos) << message;
        EXPECT_NE(message.find(word), std::string::npos) << message;
        EXPECT_EQ(message.find('\n'), std::string::npos) << message;
      }
    }
    expect_bad_input(run("info " + path(name)), name);
  }
};

TEST_F(DicomFileCheck, AVolumeWrittenByGdcmStillReads) {
  put("ct.dcm", written_by_gdcm());
  const Volume v = read_volume(path("ct.dcm"));
  ASSERT_EQ(v.geometry.size, Eigen::Vector3i(4, 3, 5));
  for (size_t n = 0; n < 60; ++n) EXPECT_EQ(v.voxels[n], float(n)) << n;
  // Without the extension too (recognised by its DICM magic).
  put("IM0001", written_by_gdcm());
  EXPECT_EQ(read_volume(path("IM0001")).voxels, v.voxels);
}

// GDCM and HDF5 live in modules the program loads when it meets their files
// (engine/plugin_loader.hpp): linked in, they took more than half of every command's start-up
// (docs/benchmarks.md, "Start-up"). The dynamic loader's log says which libraries a run loaded.
TEST_F(DicomFileCheck, GdcmIsLoadedOnlyToReadDicom) {
  const test::CliResult help = run("--help", "LD_DEBUG=files");
  ASSERT_EQ(help.code, 0) << help.err;
  ASSERT_NE(help.err.find("libITKCommon"), std::string::npos) << "no loader log";
  EXPECT_EQ(help.err.find("libgdcm"), std::string::npos);
  EXPECT_EQ(help.err.find("libITKIOGDCM"), std::string::npos);
  EXPECT_EQ(help.err.find("libhdf5"), std::string::npos);
  // An X-ray as a one-frame DICOM file: read through the module.
  using Short2 = itk::Image<uint16_t, 2>;
  auto image = Short2::New();
  image->SetRegions(Short2::RegionType(itk::Size<2>{{7, 3}}));
  image->Allocate();
  image->FillBuffer(1000);
  itk::EncapsulateMetaData<std::string>(image->GetMetaDataDictionary(), "0028|0004", "MONOCHROME2");
  auto writer = itk::ImageFileWriter<Short2>::New();
  writer->SetImageIO(itk::GDCMImageIO::New());
  writer->SetFileName(path("xray.dcm"));
  writer->SetInput(image);
  writer->Update();
  const test::CliResult info = run("info " + path("xray.dcm"), "env -u FLUORO_PLUGIN_DIR LD_DEBUG=files");
  ASSERT_EQ(info.code, 0) << info.err;
  EXPECT_NE(info.out.find("7 x 3"), std::string::npos) << info.out;
  // Loaded by the program itself (the first pid of the log), not by the child that reads the file,
  // from the program's own build tree.
  std::istringstream log(info.err);
  std::string line, first_pid, loaded;
  while (std::getline(log, line)) {
    const std::string pid = line.substr(0, line.find(':'));
    if (first_pid.empty()) first_pid = pid;
    if (line.find("libfluoro_dicom.so") != std::string::npos && line.find("dynamically loaded") != std::string::npos) {
      EXPECT_EQ(pid, first_pid) << line;
      loaded = line.substr(line.find("file=") + 5);
      loaded = loaded.substr(0, loaded.find(' '));
    }
  }
  const std::string tree = fs::canonical(fs::path(FLUORO_CLI).parent_path().parent_path()).string();
  EXPECT_EQ(loaded.rfind(tree + "/", 0), 0u) << loaded << " is not under " << tree;
}

TEST_F(DicomFileCheck, TheFuzzedFileThatKeptGdcmBusyIsRefusedAtOnce) {
  // fuzz_volume_nrrd's 1 KB input: the DICM magic at byte 128 and then an element claiming
  // 1.9 GB, which GDCM zero-filled (8.6 s, 1.8 GB) before refusing the file. What follows the
  // magic is not the File Meta Information a Part 10 file must start with, so the check stops
  // there; the tests below reach the length checks.
  const fs::path input = fs::path(FLUORO_SOURCE_DIR) / "tests" / "fuzz_regressions" / "volume_nrrd" / "sizes_beyond_file";
  fs::copy_file(input, path("s.dcm"));
  expect_refused("s.dcm", "no File Meta Information");
  // In a directory read as a DICOM series: GDCM's scan would parse it the same way.
  fs::create_directories(path("series"));
  fs::copy_file(input, path("series/IM0001"));
  try {
    read_volume(path("series"));
    ADD_FAILURE() << "the series was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(path("series/IM0001")), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no File Meta Information"), std::string::npos) << e.what();
  }
}

TEST_F(DicomFileCheck, PixelDataAsASequenceIsRefused) {
  // CI's fuzz_volume_dcm input of 2026-12-07, rebuilt by hand: Pixel Data (7FE0,0010) with VR SQ
  // and an undefined length, on which GDCM asserts (the program aborted before the check refused it).
  const fs::path input =
      fs::path(FLUORO_SOURCE_DIR) / "tests" / "fuzz_regressions" / "volume_dcm" / "pixel_data_as_a_sequence";
  fs::copy_file(input, path("sq.dcm"));
  expect_refused("sq.dcm", "the Pixel Data (7FE0,0010) at byte 202 has VR SQ, not OB or OW");
}

TEST_F(DicomFileCheck, PixelDataLongerThanTheFileIsRefused) {
  std::vector<char> b = written_by_gdcm();
  const Found pixels = find_element(b, 0x7FE0, 0x0010, "OW");
  ASSERT_GT(pixels.tag, 0u);
  ASSERT_EQ(pixels.length_bytes, 4u);
  const uint32_t length = 0x7FFFFFF0;
  std::memcpy(&b[pixels.length_at], &length, 4);
  put("long.dcm", b);
  expect_refused("long.dcm", "(7FE0,0010) at byte " + std::to_string(pixels.tag) +
                                 " states a length of 2147483632 bytes, past the end of the file");
}

TEST_F(DicomFileCheck, RowsBeyondThePixelDataAreRefused) {
  std::vector<char> b = written_by_gdcm();
  const Found rows = find_element(b, 0x0028, 0x0010, "US");
  ASSERT_GT(rows.tag, 0u);
  const uint16_t many = 60000;
  std::memcpy(&b[rows.value_at], &many, 2);
  put("rows.dcm", b);
  // 4 columns x 3 rows x 5 frames x 2 bytes written; 60000 rows describe 2,400,000 bytes.
  expect_refused("rows.dcm", "the pixel data holds 120 bytes, but Rows, Columns, Bits Allocated and Number of "
                             "Frames describe 2400000 bytes");
}

TEST_F(DicomFileCheck, ATruncatedFileIsRefused) {
  std::vector<char> b = written_by_gdcm();
  const Found rows = find_element(b, 0x0028, 0x0010, "US");
  ASSERT_GT(rows.tag, 0u);
  b.resize(rows.tag + 6);  // inside the Rows element's header
  put("cut.dcm", b);
  expect_refused("cut.dcm", "the data element at byte " + std::to_string(rows.tag) + " runs past the end of the file");
}

TEST_F(DicomFileCheck, AFileWithoutTheMagicIsNotDicom) {
  std::vector<char> b = written_by_gdcm();
  b[131] = 'X';  // "DICX"
  put("nomagic.dcm", b);
  expect_refused("nomagic.dcm", "no DICM magic");
  // Without the .dcm name it is no format read_volume knows (GDCM is not asked).
  put("nomagic", b);
  try {
    read_volume(path("nomagic"));
    ADD_FAILURE() << "read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown or unreadable volume format"), std::string::npos) << e.what();
  }
}

TEST_F(DicomFileCheck, AnUndefinedLengthOnAPlainElementIsRefused) {
  // Rows with an undefined length (0xFFFFFFFF), which only sequences and compressed pixel data
  // may have: in implicit VR it reads as a sequence, whose first "item" is Rows' value.
  std::vector<char> b = written_by_gdcm();
  const Found rows = find_element(b, 0x0028, 0x0010, "US");
  ASSERT_GT(rows.tag, 0u);
  const uint32_t undefined = 0xFFFFFFFF;
  if (rows.explicit_vr) {
    b[rows.tag + 4] = 'U';
    b[rows.tag + 5] = 'T';  // a VR with a 4-byte length after two reserved bytes
    b[rows.tag + 6] = b[rows.tag + 7] = 0;
    std::memcpy(&b[rows.tag + 8], &undefined, 4);
    put("undefined.dcm", b);
    expect_refused("undefined.dcm", "(0028,0010) at byte " + std::to_string(rows.tag) +
                                        " has an undefined length but is not a sequence");
  } else {
    std::memcpy(&b[rows.length_at], &undefined, 4);
    put("undefined.dcm", b);
    expect_refused("undefined.dcm", "at byte " + std::to_string(rows.value_at) + " where an item belongs");
  }
}

}  // namespace
}  // namespace fluoro
