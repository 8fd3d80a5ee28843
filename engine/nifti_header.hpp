#pragma once
// NIfTI-1/-2 headers checked before ITK reads them. ITK 5.2's NIfTI reader builds its direction
// matrix with VNL, which aborts the process on a NaN in the qform/sform and loops for minutes on a
// near-singular one; the NIfTI library prints "** ERROR" lines of its own for a bad dim or datatype;
// and a short file is read without complaint, the missing voxels left as garbage.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "engine/widen_to_float.hpp"

namespace fluoro {

// Throws InputError naming the path unless the (plain or gzipped) file starts with a NIfTI-1 or
// NIfTI-2 header whose dimensions, datatype, voxel sizes, data offset and qform/sform (when their
// codes say they are used) are finite and sane, and, for a single-file NIfTI, the file holds all the
// voxel bytes the header describes. An Analyze 7.5 header (no NIfTI magic) passes the same checks.
void check_nifti_header(const std::string& path);

// Where a single-file NIfTI-1 keeps its voxels, for those whose values need nothing but a widening
// to float: this machine's byte order, no scaling (ITK's rule: a slope of 0 or 1 and an intercept
// of 0), an integer or real scalar datatype, and the voxels at or after byte 352.
struct NiftiVoxels {
  uint64_t offset = 0;  // bytes from the start of the (inflated) file
  StoredType type = StoredType::u8;
  uint64_t bytes = 0;   // of the voxels
  bool gzipped = false;
};

// check_nifti_header, and the voxels' layout when read_nifti_voxels can read them (otherwise
// nullopt, and ITK's reader must). A gzipped file that it can read is not inflated here to count
// its length: read_nifti_voxels finds a short file as it reads, so the file is inflated once.
std::optional<NiftiVoxels> check_nifti_header_for_voxels(const std::string& path);

// The `count` voxels of the file (layout.bytes of them) as floats: a plain file's read straight into
// the floats (float files) or through one buffer of the stored type, a gzipped file's inflated into
// a buffer that grows as the data arrive; a cast as ITK's reader makes. Throws InputError naming the
// path when the file ends before them.
VoxelBuffer read_nifti_voxels(const std::string& path, const NiftiVoxels& layout, size_t count);

}  // namespace fluoro
