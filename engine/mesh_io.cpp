#include "engine/mesh_io.hpp"

// Small, careful readers rather than ITK's mesh IO: ITK 5.2 has no STL or PLY reader, and its OBJ
// reader neither checks that a number parsed (a bad face index is read uninitialised) nor supports
// OBJ's relative (negative) indices. Every count, index and number here is checked, so a damaged
// file is a one-line error, never a wrong surface.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string_view>

#include "engine/error.hpp"

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

// Whitespace-separated tokens of a text, one at a time.
class Tokens {
 public:
  explicit Tokens(std::string_view text) : text_(text) {}
  bool next(std::string_view& token) {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    if (pos_ >= text_.size()) return false;
    const size_t start = pos_;
    while (pos_ < text_.size() && !std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    token = text_.substr(start, pos_ - start);
    return true;
  }

 private:
  std::string_view text_;
  size_t pos_ = 0;
};

// The whole token must be a number; "nan"/"inf" parse and are caught by the finiteness check.
bool parse_number(std::string_view token, double& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  return ec == std::errc() && end == token.data() + token.size();
}

bool parse_integer(std::string_view token, long long& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  return ec == std::errc() && end == token.data() + token.size();
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

// A polygon of k >= 3 vertices as a fan of k - 2 triangles.
void add_polygon(TriangleMesh& mesh, const std::vector<int>& polygon) {
  for (size_t i = 1; i + 1 < polygon.size(); ++i) mesh.triangles.push_back({polygon[0], polygon[i], polygon[i + 1]});
}

// ---- STL --------------------------------------------------------------------------------------

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

// ---- PLY --------------------------------------------------------------------------------------

enum class PlyType { int8, uint8, int16, uint16, int32, uint32, float32, float64 };

bool ply_type(std::string_view name, PlyType& type) {
  static const std::pair<std::string_view, PlyType> names[] = {
      {"char", PlyType::int8},     {"int8", PlyType::int8},       {"uchar", PlyType::uint8},
      {"uint8", PlyType::uint8},   {"short", PlyType::int16},     {"int16", PlyType::int16},
      {"ushort", PlyType::uint16}, {"uint16", PlyType::uint16},   {"int", PlyType::int32},
      {"int32", PlyType::int32},   {"uint", PlyType::uint32},     {"uint32", PlyType::uint32},
      {"float", PlyType::float32}, {"float32", PlyType::float32}, {"double", PlyType::float64},
      {"float64", PlyType::float64}};
  for (const auto& [n, t] : names)
    if (n == name) {
      type = t;
      return true;
    }
  return false;
}

size_t ply_size(PlyType t) {
  switch (t) {
    case PlyType::int8: case PlyType::uint8: return 1;
    case PlyType::int16: case PlyType::uint16: return 2;
    case PlyType::int32: case PlyType::uint32: case PlyType::float32: return 4;
    case PlyType::float64: return 8;
  }
  return 0;
}

struct PlyProperty {
  std::string name;
  PlyType type;
  bool is_list = false;
  PlyType count_type = PlyType::uint8;
};

struct PlyElement {
  std::string name;
  size_t count = 0;
  std::vector<PlyProperty> properties;
};

// Reads one value from the body, ASCII or binary little-endian.
class PlyReader {
 public:
  PlyReader(std::string_view body, bool binary, const std::string& path)
      : body_(body), tokens_(body), binary_(binary), path_(path) {}

  double value(PlyType type) {
    if (!binary_) {
      std::string_view token;
      double v;
      if (!tokens_.next(token)) throw_input_error(path_, "truncated: the data ends before the header's counts");
      if (!parse_number(token, v)) throw_input_error(path_, "\"" + std::string(token) + "\" is not a number");
      return v;
    }
    const size_t n = ply_size(type);
    if (pos_ + n > body_.size()) throw_input_error(path_, "truncated: the data ends before the header's counts");
    const char* p = body_.data() + pos_;
    pos_ += n;
    switch (type) {
      case PlyType::int8: return load<int8_t>(p);
      case PlyType::uint8: return load<uint8_t>(p);
      case PlyType::int16: return load<int16_t>(p);
      case PlyType::uint16: return load<uint16_t>(p);
      case PlyType::int32: return load<int32_t>(p);
      case PlyType::uint32: return load<uint32_t>(p);
      case PlyType::float32: return load<float>(p);
      case PlyType::float64: return load<double>(p);
    }
    return 0;
  }

 private:
  template <class T>
  static double load(const char* p) {
    T v;
    std::memcpy(&v, p, sizeof v);  // the machine is little-endian (x86-64, AArch64)
    return static_cast<double>(v);
  }
  std::string_view body_;
  Tokens tokens_;
  bool binary_;
  size_t pos_ = 0;
  const std::string& path_;
};

TriangleMesh read_ply(const std::string& bytes, const std::string& path) {
  const size_t end = bytes.find("end_header");
  if (bytes.compare(0, 3, "ply") != 0 || end == std::string::npos)
    throw_input_error(path, "not a PLY file (no \"ply\" ... \"end_header\" header)");
  size_t body = bytes.find('\n', end);
  if (body == std::string::npos) throw_input_error(path, "truncated after end_header");
  ++body;

  std::istringstream header(bytes.substr(0, end));
  std::string line;
  std::getline(header, line);
  bool binary = false, have_format = false;
  std::vector<PlyElement> elements;
  while (std::getline(header, line)) {
    std::istringstream words(line);
    std::string key;
    if (!(words >> key) || key == "comment" || key == "obj_info") continue;
    if (key == "format") {
      std::string format;
      words >> format;
      if (format == "ascii") binary = false;
      else if (format == "binary_little_endian") binary = true;
      else throw_input_error(path, "PLY format \"" + format + "\" is not supported (ascii and binary_little_endian are)");
      have_format = true;
    } else if (key == "element") {
      PlyElement e;
      long long count = -1;
      std::string count_text;
      if (!(words >> e.name >> count_text) || !parse_integer(count_text, count) || count < 0)
        throw_input_error(path, "bad element line \"" + line + "\"");
      e.count = size_t(count);
      elements.push_back(e);
    } else if (key == "property") {
      if (elements.empty()) throw_input_error(path, "a property before any element");
      PlyProperty p;
      std::string type;
      words >> type;
      if (type == "list") {
        std::string count_type, item_type;
        words >> count_type >> item_type >> p.name;
        if (!ply_type(count_type, p.count_type) || !ply_type(item_type, p.type) || p.name.empty())
          throw_input_error(path, "bad property line \"" + line + "\"");
        p.is_list = true;
      } else if (!ply_type(type, p.type) || !(words >> p.name)) {
        throw_input_error(path, "bad property line \"" + line + "\"");
      }
      elements.back().properties.push_back(p);
    } else {
      throw_input_error(path, "unknown header line \"" + line + "\"");
    }
  }
  if (!have_format) throw_input_error(path, "the PLY header has no format line");

  TriangleMesh mesh;
  PlyReader reader(std::string_view(bytes).substr(body), binary, path);
  bool have_vertices = false;
  for (const PlyElement& e : elements) {
    const bool vertex = e.name == "vertex", face = e.name == "face";
    int axis[3] = {-1, -1, -1};
    for (size_t k = 0; k < e.properties.size(); ++k)
      for (int a = 0; a < 3; ++a)
        if (e.properties[k].name == std::string(1, char('x' + a)) && !e.properties[k].is_list) axis[a] = int(k);
    if (vertex) {
      if (axis[0] < 0 || axis[1] < 0 || axis[2] < 0) throw_input_error(path, "the vertex element lacks x, y or z");
      have_vertices = true;
    }
    for (size_t i = 0; i < e.count; ++i) {
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      for (size_t k = 0; k < e.properties.size(); ++k) {
        const PlyProperty& prop = e.properties[k];
        if (!prop.is_list) {
          const double v = reader.value(prop.type);
          for (int a = 0; a < 3; ++a)
            if (vertex && axis[a] == int(k)) p[a] = v;
          continue;
        }
        const double n = reader.value(prop.count_type);
        if (!(n >= 0) || n != std::floor(n) || n > 1e6) throw_input_error(path, "a list with a bad length");
        const bool indices = face && (prop.name == "vertex_indices" || prop.name == "vertex_index");
        std::vector<int> polygon;
        for (int j = 0; j < int(n); ++j) {
          const double index = reader.value(prop.type);
          if (index != std::floor(index) || std::abs(index) > 2e9)
            throw_input_error(path, "face " + std::to_string(i) + " has an index that is not an integer");
          if (indices) polygon.push_back(int(index));
        }
        if (indices) {
          if (polygon.size() < 3) throw_input_error(path, "face " + std::to_string(i) + " has fewer than 3 vertices");
          add_polygon(mesh, polygon);
        }
      }
      if (vertex) mesh.vertices.push_back(p);
    }
  }
  if (!have_vertices) throw_input_error(path, "the PLY file has no vertex element");
  return mesh;
}

// ---- OBJ --------------------------------------------------------------------------------------

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

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

}  // namespace

TriangleMesh read_mesh(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext != ".stl" && ext != ".ply" && ext != ".obj")
    throw_input_error(path, "unknown mesh format \"" + ext + "\" (expected .stl, .ply or .obj)");
  const std::string bytes = slurp(path);
  if (bytes.empty()) throw_input_error(path, "the file is empty");
  TriangleMesh mesh = ext == ".stl" ? read_stl(bytes, path) : ext == ".ply" ? read_ply(bytes, path) : read_obj(bytes, path);
  validate(mesh, path);
  return mesh;
}

}  // namespace fluoro
