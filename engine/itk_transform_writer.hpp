#pragma once
// A CT pose as an ITK transform file, for 3D Slicer, SimpleITK and ITK (docs/cli.md, "ITK
// transform files").
//
// Direction: an ITK transform maps points of the fixed (output) space to the moving space, the way
// a resampler pulls moving-image values onto the fixed grid. The file therefore holds
// T_ct_world = T_world_ct^-1 (world points to CT points): resampling the CT with it puts the CT in
// the world frame, and Slicer, which applies the inverse of a file's resampling transform to move a
// node, moves the CT by T_world_ct. Coordinates are written as they are: the CT frame is ITK's own
// physical (LPS) space, and the world frame is taken as LPS too, as ITK takes every space.
#include <string>

#include "engine/pose.hpp"

namespace fluoro {

// True for the names write_itk_transform takes: .tfm or .txt (ITK's text format), .h5 or .hdf5.
bool is_itk_transform_path(const std::string& path);

// Loads what writing `path` needs (the HDF5 module for .h5 and .hdf5, engine/plugin_loader.hpp),
// so that a program can fail on a broken installation before its work rather than after it.
void prepare_itk_transform_writer(const std::string& path);

// Writes T_world_ct^-1 as an AffineTransform_double_3_3 (center 0) by the name's extension.
// Atomic. Throws InputError naming the path for another extension or a failed write.
void write_itk_transform(const Pose& T_world_ct, const std::string& path);

}  // namespace fluoro
