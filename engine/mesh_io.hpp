#pragma once
// Surface mesh files: STL (binary and ASCII), PLY (ASCII and binary little-endian) and Wavefront
// OBJ, chosen by the file's extension. Readers check every count, index and number they read.
#include <string>

#include "engine/triangle_mesh.hpp"

namespace fluoro {

// Reads MESH.stl|.ply|.obj (extension case-insensitive); polygons are split into triangle fans.
// Throws InputError naming the path for a missing file, an unknown extension, a truncated or
// malformed file, an index out of range, a non-finite coordinate or a mesh without triangles.
TriangleMesh read_mesh(const std::string& path);

}  // namespace fluoro
