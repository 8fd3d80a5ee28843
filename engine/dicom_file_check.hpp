#pragma once
// DICOM files checked before GDCM reads them. GDCM sizes a data element's buffer by the length the
// file states and zero-fills it before reading: a fuzzed 1 KB file with the DICM magic and an
// element claiming 1.9 GB took 8.6 s and 1.8 GB of memory inside GDCM's probe (CanReadFile) before
// the one-line refusal (docs/fuzzing.md, fuzz_volume_nrrd's "sizes_beyond_file" named .dcm).
#include <string>

namespace fluoro {

// Throws InputError naming the path unless the file is a DICOM Part 10 file (a 128-byte preamble,
// "DICM", then the File Meta Information, group 0002, in explicit VR little endian) whose data
// elements, walked one by one in the encoding its transfer syntax names (implicit or explicit VR,
// little or big endian; deflated data sets are refused), each fit inside the file and inside the
// sequence or item that holds them, with sequences nested at most 16 deep, whose Pixel Data
// elements have VR OB, OW or UN (GDCM asserts on a sequence), and whose pixel data,
// when Rows, Columns and Bits Allocated are given, is neither shorter than they describe
// (uncompressed) nor more than 4,128 times the file's size (compressed: deflate's 1032:1 on a
// 4-byte voxel, the bound read_volume puts on every format). The check reads the element headers
// and the few image-size values only, never the pixel data.
void check_dicom_file(const std::string& path);

// True when the file has the DICOM Part 10 magic ("DICM" after a 128-byte preamble).
bool has_dicom_magic(const std::string& path);

}  // namespace fluoro
