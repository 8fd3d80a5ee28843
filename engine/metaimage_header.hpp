#pragma once
// MetaImage (.mha, .mhd) headers checked before ITK reads them. MetaIO prints its own complaints
// ("DimSize required and not defined.", "Uncompress failed") to stderr, an unknown ElementType
// reaches ITK as an exception outside the reader, and a short file is read without an error.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "engine/widen_to_float.hpp"

namespace fluoro {

// Throws InputError naming the path unless the text header has NDims, DimSize, ElementType and
// ElementDataFile with sane values (positive sizes, a scalar element type, finite positive spacing,
// finite offset, a finite non-degenerate TransformMatrix) and the data file (the same one for
// "LOCAL") exists and holds the bytes the header describes (compressed data must state its
// CompressedDataSize, as ITK and MetaIO write it).
void check_metaimage_header(const std::string& path);

// Where a single-file MetaImage keeps its voxels, for those read_metaimage_voxels reads itself: the
// form ITK writes a 3D scalar image in (binary data after the header, "ElementDataFile = LOCAL",
// this machine's byte order, raw or zlib-compressed, one channel, an element type whose size MetaIO
// and this machine agree on, no HeaderSize and no intensity function).
struct MetaImageVoxels {
  uint64_t offset = 0;  // bytes from the start of the file
  StoredType type = StoredType::u8;
  uint64_t bytes = 0;             // of the voxels
  uint64_t compressed_bytes = 0;  // 0: stored raw; else CompressedDataSize, zlib or gzip
};

// check_metaimage_header, and the voxels' layout when read_metaimage_voxels can read them
// (otherwise nullopt, and ITK's reader must).
std::optional<MetaImageVoxels> check_metaimage_header_for_voxels(const std::string& path);

// The `count` voxels of the file as floats, a cast as ITK's reader makes, read straight into the
// floats (float files) or through one buffer of the stored type; compressed data are inflated as
// they are read. Throws InputError naming the path when the file or the compressed stream ends
// before the voxels do, or the stream is corrupt (MetaIO would print "Uncompress failed" and leave
// the rest of the voxels as they were).
VoxelBuffer read_metaimage_voxels(const std::string& path, const MetaImageVoxels& layout, size_t count);

}  // namespace fluoro
