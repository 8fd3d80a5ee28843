#pragma once
// A TIFF's first directory checked before ITK reads it. ITK 5.2's TIFFImageIO copies the DateTime
// tag (306) as the 20 bytes the TIFF standard fixes for it, while libtiff keeps only the bytes up
// to the first NUL: a shorter or NUL-cut DateTime is read past its end (found by fuzz_image_tif
// under AddressSanitizer; tests/fuzz_regressions/image_tif/).
#include <string>

namespace fluoro {

// Throws InputError naming the path when the first image directory of a classic or BigTIFF file
// has a DateTime tag whose text is not 19 characters and a NUL. Other problems are left to
// libtiff, which reports them (a file that is not TIFF at all is not this check's business).
void check_tiff_tags(const std::string& path);

}  // namespace fluoro
