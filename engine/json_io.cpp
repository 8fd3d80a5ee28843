#include "engine/json_io.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "engine/atomic_file.hpp"
#include "engine/error.hpp"

namespace fluoro {
namespace {

using nlohmann::json;

const json& require_key(const json& doc, const char* key, const std::string& path) {
  const auto it = doc.find(key);
  if (it == doc.end()) throw_input_error(path, std::string("missing key \"") + key + "\"");
  return *it;
}

template <int Rows, int Cols>
Eigen::Matrix<double, Rows, Cols> parse_matrix(const json& value, const char* name,
                                               const std::string& path) {
  const auto bad = [&]() {
    throw_input_error(path, std::string(name) + " must be a " + std::to_string(Rows) + "x" +
                                std::to_string(Cols) + " array of numbers");
  };
  if (!value.is_array() || value.size() != Rows) bad();
  Eigen::Matrix<double, Rows, Cols> m;
  for (int r = 0; r < Rows; ++r) {
    const json& row = value[size_t(r)];
    if (!row.is_array() || row.size() != Cols) bad();
    for (int c = 0; c < Cols; ++c) {
      if (!row[size_t(c)].is_number()) bad();
      m(r, c) = row[size_t(c)].get<double>();
    }
  }
  return m;
}

// A flat [x, y, z]; the nested column form [[x], [y], [z]] (OpenCV's tvec) is accepted too.
template <int N>
Eigen::Matrix<double, N, 1> parse_vector(const json& value, const char* name,
                                         const std::string& path) {
  const auto bad = [&]() {
    throw_input_error(path,
                      std::string(name) + " must be an array of " + std::to_string(N) + " numbers");
  };
  if (!value.is_array() || value.size() != N) bad();
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i) {
    const json* e = &value[size_t(i)];
    if (e->is_array() && e->size() == 1) e = &(*e)[0];
    if (!e->is_number()) bad();
    v[i] = e->get<double>();
  }
  return v;
}

int parse_size(const json& value, const char* name, const std::string& path) {
  // 512.0 is accepted as 512: some writers emit every number as a double.
  const double d = value.is_number() ? value.get<double>() : 0.0;
  if (!value.is_number() || !(d >= 1) || d > 1e6 || d != std::floor(d))
    throw_input_error(path, std::string(name) + " must be a positive integer");
  return int(d);
}

json read_object(const std::string& path) {
  json doc = read_json(path);
  if (!doc.is_object()) throw_input_error(path, "expected a JSON object at the top level");
  return doc;
}

template <class Matrix>
json matrix_to_json(const Matrix& m) {
  json rows = json::array();
  for (int r = 0; r < m.rows(); ++r) {
    json row = json::array();
    for (int c = 0; c < m.cols(); ++c) row.push_back(m(r, c));
    rows.push_back(std::move(row));
  }
  return rows;
}

}  // namespace

json read_json(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw_input_error(path, "file not found");
  if (std::filesystem::is_directory(path, ec))
    throw_input_error(path, "is a directory, expected a JSON file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_input_error(path, "cannot open file");
  try {
    return json::parse(in);
  } catch (const json::parse_error& e) {
    // e.what() is "[json.exception.parse_error.101] parse error at line L, column C: ..."; keep the
    // part after the tag, on one line.
    std::string detail = e.what();
    if (const size_t p = detail.find("] "); p != std::string::npos) detail = detail.substr(p + 2);
    for (char& c : detail)
      if (c == '\n' || c == '\r') c = ' ';
    throw_input_error(path, "invalid JSON at byte " + std::to_string(e.byte) + " (" + detail + ")");
  } catch (const json::exception& e) {
    // A number too large for a double (1e400) is out_of_range, not parse_error: still bad input.
    std::string detail = e.what();
    if (const size_t p = detail.find("] "); p != std::string::npos) detail = detail.substr(p + 2);
    throw_input_error(path, "unreadable JSON (" + detail + ")");
  }
}

json read_json_of_kind(const std::string& path, const std::string& kind) {
  json doc = read_json(path);
  if (!doc.is_object()) throw_input_error(path, "expected a JSON object at the top level");
  if (!doc.contains("kind") || doc["kind"] != kind) throw_input_error(path, "expected \"kind\": \"" + kind + "\"");
  return doc;
}

void write_json(const json& document, const std::string& path) {
  write_file_atomic(path, [&](const std::string& file) {
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error(file + ": cannot create file");
    out << document.dump(2) << '\n';
    out.close();
    if (!out) throw std::runtime_error(file + ": cannot write file");
  });
}

PinholeCamera read_camera(const std::string& path) {
  const json doc = read_object(path);
  const int width = parse_size(require_key(doc, "width", path), "width", path);
  const int height = parse_size(require_key(doc, "height", path), "height", path);

  PinholeCamera camera;
  if (doc.contains("K") || !doc.contains("P")) {
    camera.width = width;
    camera.height = height;
    camera.K = parse_matrix<3, 3>(require_key(doc, "K", path), "K", path);
    camera.R = parse_matrix<3, 3>(require_key(doc, "R", path), "R", path);
    camera.t = parse_vector<3>(require_key(doc, "t", path), "t", path);
  } else {
    camera = camera_from_projection(parse_matrix<3, 4>(doc["P"], "P", path), width, height, path);
  }
  if (const auto it = doc.find("pixel_spacing_mm"); it != doc.end() && !it->is_null())
    camera.pixel_spacing_mm = parse_vector<2>(*it, "pixel_spacing_mm", path);
  validate_camera(camera, path);
  return camera;
}

json camera_to_json(const PinholeCamera& camera) {
  json doc;
  doc["width"] = camera.width;
  doc["height"] = camera.height;
  doc["K"] = matrix_to_json(camera.K);
  doc["R"] = matrix_to_json(camera.R);
  doc["t"] = {camera.t.x(), camera.t.y(), camera.t.z()};
  if (camera.pixel_spacing_mm)
    doc["pixel_spacing_mm"] = {camera.pixel_spacing_mm->x(), camera.pixel_spacing_mm->y()};
  return doc;
}

void write_camera(const PinholeCamera& camera, const std::string& path) {
  write_json(camera_to_json(camera), path);
}

Pose read_pose(const std::string& path) {
  const json doc = read_object(path);
  const Eigen::Matrix4d m =
      parse_matrix<4, 4>(require_key(doc, "T_world_ct", path), "T_world_ct", path);
  return pose_from_matrix(m, path);
}

json pose_to_json(const Pose& pose) { return json{{"T_world_ct", matrix_to_json(pose.matrix())}}; }

void write_pose(const Pose& pose, const std::string& path) { write_json(pose_to_json(pose), path); }

}  // namespace fluoro
