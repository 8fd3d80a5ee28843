#pragma once
// Volume files through ITK: NIfTI (.nii, .nii.gz), MetaImage (.mha, .mhd), NRRD (.nrrd, .nhdr),
// and DICOM series (a directory). Geometry is ITK's (LPS physical space, direction honoured).
#include <string>

#include "engine/volume.hpp"

namespace fluoro {

// Reads any supported volume as float voxels. Throws InputError naming the path for a missing,
// unreadable or truncated file, a non-scalar or non-3D image, zero/negative spacing, or NaN voxels.
Volume read_volume(const std::string& path);

// Writes by extension (.nii, .nii.gz, .mha, .mhd, .nrrd), atomically.
void write_volume(const Volume& volume, const std::string& path);

}  // namespace fluoro
