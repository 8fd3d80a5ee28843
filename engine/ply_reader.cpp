// PLY files: ASCII and binary little-endian, any element and property layout (vertex x, y, z and
// a face list named vertex_indices or vertex_index are used; every other element is read past).
#include "engine/mesh_format_readers.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <sstream>

#include "engine/error.hpp"

namespace fluoro::mesh_detail {
namespace {

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

}  // namespace

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
    // Every record reads at least one value, so a count larger than the file ends in "truncated";
    // records of nothing would loop up to the count (10^12 in a fuzzed header) reading nothing.
    if (e.properties.empty() && e.count > 0)
      throw_input_error(path, "element \"" + e.name + "\" has no properties");
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
          if (!indices) continue;  // another list (texture coordinates, ...): read past it
          if (index != std::floor(index) || std::abs(index) > 2e9)
            throw_input_error(path, "face " + std::to_string(i) + " has an index that is not an integer");
          polygon.push_back(int(index));
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

}  // namespace fluoro::mesh_detail
