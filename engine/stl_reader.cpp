// STL files: binary (50-byte records of float triangles) and ASCII ("solid ... facet ... vertex").
#include "engine/mesh_format_readers.hpp"

#include <cstdint>
#include <cstring>

#include "engine/error.hpp"

namespace fluoro::mesh_detail {
namespace {

TriangleMesh read_binary_stl(const std::string& bytes, uint32_t count) {
  TriangleMesh mesh;
  mesh.vertices.reserve(size_t(count) * 3);
  mesh.triangles.reserve(count);
  for (uint32_t t = 0; t < count; ++t) {
    const char* record = bytes.data() + 84 + size_t(t) * 50;
    float xyz[9];
    std::memcpy(xyz, record + 12, sizeof xyz);  // skip the stored normal: it is recomputed from the vertices
    const int base = static_cast<int>(mesh.vertices.size());
    for (int v = 0; v < 3; ++v) mesh.vertices.emplace_back(xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]);
    mesh.triangles.push_back({base, base + 1, base + 2});
  }
  return mesh;
}

TriangleMesh read_ascii_stl(std::string_view text, const std::string& path) {
  TriangleMesh mesh;
  Tokens tokens(text);
  std::string_view token;
  int in_facet = -1;  // vertices seen in the open facet, -1 outside a facet
  while (tokens.next(token)) {
    if (token == "facet") {
      if (in_facet >= 0) throw_input_error(path, "facet " + std::to_string(mesh.triangles.size()) + " is not closed");
      in_facet = 0;
    } else if (token == "vertex") {
      if (in_facet < 0 || in_facet >= 3)
        throw_input_error(path, "a vertex outside a facet or a facet with more than 3 vertices");
      Eigen::Vector3d p;
      for (int i = 0; i < 3; ++i)
        if (!tokens.next(token) || !parse_number(token, p[i]))
          throw_input_error(path, "facet " + std::to_string(mesh.triangles.size()) + " has a vertex that is not 3 numbers");
      mesh.vertices.push_back(p);
      ++in_facet;
    } else if (token == "endfacet") {
      if (in_facet != 3)
        throw_input_error(path, "facet " + std::to_string(mesh.triangles.size()) + " does not have 3 vertices");
      const int base = static_cast<int>(mesh.vertices.size()) - 3;
      mesh.triangles.push_back({base, base + 1, base + 2});
      in_facet = -1;
    }
  }
  if (in_facet >= 0) throw_input_error(path, "truncated: the last facet is not closed");
  return mesh;
}

}  // namespace

TriangleMesh read_stl(const std::string& bytes, const std::string& path) {
  // A binary STL's size is exactly 84 + 50 n; its 80-byte header may itself start with "solid",
  // so the size decides, not the first word.
  if (bytes.size() >= 84) {
    uint32_t count;
    std::memcpy(&count, bytes.data() + 80, 4);
    if (bytes.size() == 84 + size_t(count) * 50) return read_binary_stl(bytes, count);
  }
  const size_t first = bytes.find_first_not_of(" \t\r\n");
  if (first == std::string::npos || bytes.compare(first, 5, "solid") != 0)
    throw_input_error(path, "neither an ASCII STL (\"solid ...\") nor a binary STL whose size matches its triangle count");
  return read_ascii_stl(std::string_view(bytes).substr(first + 5), path);
}

}  // namespace fluoro::mesh_detail
