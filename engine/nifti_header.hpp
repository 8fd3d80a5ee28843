#pragma once
// NIfTI-1/-2 headers checked before ITK reads them. ITK 5.2's NIfTI reader builds its direction
// matrix with VNL, which aborts the process on a NaN in the qform/sform and loops for minutes on a
// near-singular one; the NIfTI library prints "** ERROR" lines of its own for a bad dim or datatype;
// and a short file is read without complaint, the missing voxels left as garbage.
#include <string>

namespace fluoro {

// Throws InputError naming the path unless the (plain or gzipped) file starts with a NIfTI-1 or
// NIfTI-2 header whose dimensions, datatype, voxel sizes, data offset and qform/sform (when their
// codes say they are used) are finite and sane, and, for a single-file NIfTI, the file holds all the
// voxel bytes the header describes. An Analyze 7.5 header (no NIfTI magic) passes the same checks.
void check_nifti_header(const std::string& path);

}  // namespace fluoro
