#pragma once
// Internal to the mesh readers (engine/mesh_io.cpp and one reader per format): the format readers
// and the text helpers they share. Every reader throws InputError naming `path` on damage.
#include <cctype>
#include <charconv>
#include <string>
#include <string_view>
#include <vector>

#include "engine/triangle_mesh.hpp"

namespace fluoro::mesh_detail {

// STL, binary (its size is exactly 84 + 50 n) or ASCII.
TriangleMesh read_stl(const std::string& bytes, const std::string& path);
// PLY, ASCII or binary little-endian, any property layout; polygons as triangle fans.
TriangleMesh read_ply(const std::string& bytes, const std::string& path);
// Wavefront OBJ: `v` and `f` (i, i/t, i//n, i/t/n, negative relative indices); the rest skipped.
TriangleMesh read_obj(const std::string& text, const std::string& path);

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
inline bool parse_number(std::string_view token, double& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  return ec == std::errc() && end == token.data() + token.size();
}

inline bool parse_integer(std::string_view token, long long& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  return ec == std::errc() && end == token.data() + token.size();
}

// A polygon of k >= 3 vertices as a fan of k - 2 triangles.
inline void add_polygon(TriangleMesh& mesh, const std::vector<int>& polygon) {
  for (size_t i = 1; i + 1 < polygon.size(); ++i) mesh.triangles.push_back({polygon[0], polygon[i], polygon[i + 1]});
}

}  // namespace fluoro::mesh_detail
