#pragma once
// MetaImage (.mha, .mhd) headers checked before ITK reads them. MetaIO prints its own complaints
// ("DimSize required and not defined.", "Uncompress failed") to stderr, an unknown ElementType
// reaches ITK as an exception outside the reader, and a short file is read without an error.
#include <string>

namespace fluoro {

// Throws InputError naming the path unless the text header has NDims, DimSize, ElementType and
// ElementDataFile with sane values (positive sizes, a scalar element type, finite positive spacing,
// finite offset, a finite non-degenerate TransformMatrix) and the data file (the same one for
// "LOCAL") exists and holds the bytes the header describes (compressed data must state its
// CompressedDataSize, as ITK and MetaIO write it).
void check_metaimage_header(const std::string& path);

}  // namespace fluoro
