// Wavefront OBJ files: vertices and faces; normals, texture coordinates, groups and materials do
// not shape the surface and are skipped.
#include "engine/mesh_format_readers.hpp"

#include <sstream>

#include "engine/error.hpp"

namespace fluoro::mesh_detail {

TriangleMesh read_obj(const std::string& text, const std::string& path) {
  TriangleMesh mesh;
  std::istringstream in(text);
  std::string line;
  size_t line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    const auto bad = [&](const std::string& problem) {
      throw_input_error(path, "line " + std::to_string(line_number) + ": " + problem);
    };
    Tokens tokens(line);
    std::string_view key, token;
    if (!tokens.next(key)) continue;
    if (key == "v") {
      Eigen::Vector3d p;
      for (int i = 0; i < 3; ++i)
        if (!tokens.next(token) || !parse_number(token, p[i])) bad("a vertex needs 3 numbers");
      mesh.vertices.push_back(p);
    } else if (key == "f") {
      std::vector<int> polygon;
      while (tokens.next(token)) {
        // "i", "i/t", "i//n" or "i/t/n": the vertex index is before the first slash; negative
        // indices count back from the latest vertex.
        long long index = 0;
        if (!parse_integer(token.substr(0, token.find('/')), index) || index == 0)
          bad("face vertex \"" + std::string(token) + "\" is not a vertex index");
        const long long n = static_cast<long long>(mesh.vertices.size());
        const long long zero_based = index > 0 ? index - 1 : n + index;
        if (zero_based < 0 || zero_based >= n) bad("face vertex " + std::to_string(index) + " is out of range");
        polygon.push_back(int(zero_based));
      }
      if (polygon.size() < 3) bad("a face needs at least 3 vertices");
      add_polygon(mesh, polygon);
    }
    // Everything else (normals, texture coordinates, groups, materials, lines) does not shape
    // the surface and is skipped.
  }
  return mesh;
}

}  // namespace fluoro::mesh_detail
