#include "engine/mesh_io.hpp"

// Small, careful readers rather than ITK's mesh IO: ITK 5.2 has no STL or PLY reader, and its OBJ
// reader neither checks that a number parsed (a bad face index is read uninitialised) nor supports
// OBJ's relative (negative) indices. Every count, index and number here is checked, so a damaged
// file is a one-line error, never a wrong surface.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "engine/error.hpp"
#include "engine/file_names.hpp"
#include "engine/mesh_format_readers.hpp"

namespace fluoro {
namespace {

std::string slurp(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw_input_error(path, "file not found");
  if (std::filesystem::is_directory(path, ec)) throw_input_error(path, "is a directory, expected a mesh file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_input_error(path, "cannot open file");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void validate(const TriangleMesh& mesh, const std::string& path) {
  if (mesh.triangles.empty()) throw_input_error(path, "the mesh has no triangles");
  for (size_t i = 0; i < mesh.vertices.size(); ++i)
    if (!mesh.vertices[i].allFinite()) throw_input_error(path, "vertex " + std::to_string(i) + " is not finite");
  const long long n = static_cast<long long>(mesh.vertices.size());
  for (size_t t = 0; t < mesh.triangles.size(); ++t)
    for (int v : mesh.triangles[t])
      if (v < 0 || v >= n)
        throw_input_error(path, "triangle " + std::to_string(t) + " refers to vertex " + std::to_string(v) +
                                    " of " + std::to_string(n));
}


}  // namespace

TriangleMesh read_mesh(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext != ".stl" && ext != ".ply" && ext != ".obj")
    throw_input_error(path, "unknown mesh format \"" + ext + "\" (expected .stl, .ply or .obj)");
  const std::string bytes = slurp(path);
  if (bytes.empty()) throw_input_error(path, "the file is empty");
  TriangleMesh mesh = ext == ".stl" ? mesh_detail::read_stl(bytes, path)
                                      : ext == ".ply" ? mesh_detail::read_ply(bytes, path)
                                                      : mesh_detail::read_obj(bytes, path);
  validate(mesh, path);
  return mesh;
}

}  // namespace fluoro
