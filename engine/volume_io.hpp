#pragma once
// Volume files through ITK: NIfTI (.nii, .nii.gz), MetaImage (.mha, .mhd), NRRD (.nrrd, .nhdr),
// and DICOM series (a directory); and 2D images in the first three formats. Geometry is ITK's
// (LPS physical space, direction honoured).
#include <string>

#include "engine/volume.hpp"

namespace fluoro {

// Reads any supported volume as float voxels. Throws InputError naming the path for a missing,
// unreadable or truncated file, a non-scalar or non-3D image, zero/negative spacing, or NaN voxels.
Volume read_volume(const std::string& path);

// A 2D image held in a volume format (NIfTI, MetaImage, NRRD: a DRR `fluoro drr`, ITK or RTK
// wrote), or a 3D one a single slice thick, with every check read_volume makes, as a volume one
// voxel deep (a 2D file's missing axis: unit spacing, zero origin). Throws InputError naming the
// path for anything else, a volume of several slices included.
Volume read_planar_volume(const std::string& path);

// Whether the name is one of the volume formats' (.nii, .nii.gz, .mha, .mhd, .nrrd, .nhdr; any case).
bool is_volume_file_name(const std::string& path);

// Whether a NIfTI, MetaImage or NRRD file's header describes a 2D image, after the format's own
// header check (which throws InputError naming the path); false for any other name, and for a
// header ITK cannot read (read_volume then says what is wrong). For commands that take a volume or
// an image by the same names (fluoro info).
bool is_2d_image_file(const std::string& path);

// Writes by extension (.nii, .nii.gz, .mha, .mhd, .nrrd), atomically.
void write_volume(const Volume& volume, const std::string& path);

}  // namespace fluoro
