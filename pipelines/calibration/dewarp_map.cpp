// The map's evaluation, its field of view, the cached remap tables and MAP.json (de)serialisation.
#include "pipelines/calibration/dewarp_map.hpp"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <mutex>
#include <opencv2/imgproc.hpp>

#include "engine/error.hpp"
#include "engine/image_mat.hpp"
#include "engine/json_io.hpp"

namespace fluoro {

struct DewarpMap::Cache {
  std::once_flag once;
  std::pair<cv::Mat, cv::Mat> tables;
};

DewarpModel parse_dewarp_model(const std::string& name) {
  if (name == "polynomial") return DewarpModel::polynomial;
  if (name == "bilinear") return DewarpModel::bilinear;
  throw_input_error("--model " + name, "expected polynomial or bilinear");
}

std::string dewarp_model_name(DewarpModel model) { return model == DewarpModel::polynomial ? "polynomial" : "bilinear"; }

bool DewarpLattice::is_covered(int i, int j) const {
  if (i < i_min || i > i_max || j < j_min || j > j_max) return false;
  return covered[size_t(j - j_min) * size_t(i_max - i_min + 1) + size_t(i - i_min)] != 0;
}

DewarpMap::DewarpMap(DewarpModel model, int width, int height, DewarpLattice lattice, PolynomialMap2 inverse,
                     PolynomialMap2 forward_guess, std::vector<Eigen::Vector2d> bilinear_nodes_px)
    : model_(model),
      width_(width),
      height_(height),
      lattice_(std::move(lattice)),
      inverse_(std::move(inverse)),
      forward_guess_(std::move(forward_guess)),
      nodes_(std::move(bilinear_nodes_px)),
      cache_(std::make_shared<Cache>()) {}

bool DewarpMap::in_field_of_view(const Eigen::Vector2d& corrected) const {
  // Within one pitch (per axis) of a covered node.
  const Eigen::Vector2d g = (corrected - lattice_.origin_px) / lattice_.pitch_px;
  if (!g.allFinite() || g.cwiseAbs().maxCoeff() > 1e6) return false;  // and no int overflow below
  for (int j = int(std::ceil(g.y() - 1)); j <= int(std::floor(g.y() + 1)); ++j)
    for (int i = int(std::ceil(g.x() - 1)); i <= int(std::floor(g.x() + 1)); ++i)
      if (lattice_.is_covered(i, j)) return true;
  return false;
}

Eigen::Vector2d DewarpMap::bilinear(const Eigen::Vector2d& corrected) const {
  const Eigen::Vector2d g = (corrected - lattice_.origin_px) / lattice_.pitch_px;
  const int ni = lattice_.i_max - lattice_.i_min + 3, nj = lattice_.j_max - lattice_.j_min + 3;
  // Node grid starts at (i_min - 1, j_min - 1); cells outside extrapolate the border cell.
  const double gx = g.x() - (lattice_.i_min - 1), gy = g.y() - (lattice_.j_min - 1);
  // Clamped as doubles: a wild Newton step must not overflow the conversion to int.
  const int ci = int(std::clamp(std::floor(gx), 0.0, double(ni - 2))), cj = int(std::clamp(std::floor(gy), 0.0, double(nj - 2)));
  const double fx = gx - ci, fy = gy - cj;
  auto node = [&](int i, int j) -> const Eigen::Vector2d& { return nodes_[size_t(j) * size_t(ni) + size_t(i)]; };
  return (1 - fy) * ((1 - fx) * node(ci, cj) + fx * node(ci + 1, cj)) + fy * ((1 - fx) * node(ci, cj + 1) + fx * node(ci + 1, cj + 1));
}

Eigen::Vector2d DewarpMap::to_distorted(const Eigen::Vector2d& corrected) const {
  return model_ == DewarpModel::polynomial ? inverse_(corrected) : bilinear(corrected);
}

std::optional<Eigen::Vector2d> DewarpMap::distort_point(const Eigen::Vector2d& corrected) const {
  if (!in_field_of_view(corrected)) return std::nullopt;
  return to_distorted(corrected);
}

std::optional<Eigen::Vector2d> DewarpMap::correct_point(const Eigen::Vector2d& distorted) const {
  if (!distorted.allFinite()) return std::nullopt;
  // Newton on the model from the forward polynomial's guess, so points and images agree exactly.
  Eigen::Vector2d x = forward_guess_(distorted);
  bool converged = false;
  for (int it = 0; it < 20 && x.allFinite(); ++it) {
    const Eigen::Vector2d r = to_distorted(x) - distorted;
    if (r.norm() < 1e-9) {
      converged = true;
      break;
    }
    const double h = 1e-3;
    Eigen::Matrix2d J;
    J.col(0) = (to_distorted(x + Eigen::Vector2d(h, 0)) - to_distorted(x - Eigen::Vector2d(h, 0))) / (2 * h);
    J.col(1) = (to_distorted(x + Eigen::Vector2d(0, h)) - to_distorted(x - Eigen::Vector2d(0, h))) / (2 * h);
    if (!(std::abs(J.determinant()) > 1e-12)) break;
    x -= J.inverse() * r;
  }
  if (!converged || !in_field_of_view(x)) return std::nullopt;
  return x;
}

const std::pair<cv::Mat, cv::Mat>& DewarpMap::remap_tables() const {
  std::call_once(cache_->once, [this] {
    cv::Mat mx(height_, width_, CV_32F), my(height_, width_, CV_32F);
    // Isolated: a caller's own parallel loop must not steal work into this call_once and re-enter it.
    tbb::this_task_arena::isolate([&] { tbb::parallel_for(0, height_, [&](int v) {
      for (int u = 0; u < width_; ++u) {
        const Eigen::Vector2d c(u, v);
        const bool in = in_field_of_view(c);
        const Eigen::Vector2d d = in ? to_distorted(c) : Eigen::Vector2d(-10, -10);  // far outside: border 0
        mx.at<float>(v, u) = float(d.x());
        my.at<float>(v, u) = float(d.y());
      }
    }); });
    // Fixed-point tables (1/32 px): remap runs several times faster than with float tables.
    cv::convertMaps(mx, my, cache_->tables.first, cache_->tables.second, CV_16SC2);
  });
  return cache_->tables;
}

cv::Mat DewarpMap::correct_image(const cv::Mat& distorted) const {
  if (distorted.cols != width_ || distorted.rows != height_)
    throw_input_error("image", "is " + std::to_string(distorted.cols) + "x" + std::to_string(distorted.rows) +
                                   ", the map is for " + std::to_string(width_) + "x" + std::to_string(height_));
  const auto& [m1, m2] = remap_tables();
  cv::Mat out;
  cv::remap(distorted, out, m1, m2, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar::all(0));
  return out;
}

Image DewarpMap::correct_image(const Image& distorted) const {
  const cv::Mat in = mat_view(distorted);
  const cv::Mat out = correct_image(in);
  Image result(out.cols, out.rows);
  std::copy(out.begin<float>(), out.end<float>(), result.pixels.begin());
  return result;
}

nlohmann::json DewarpMap::to_json() const {
  using nlohmann::json;
  json covered = json::array();
  const int ni = lattice_.i_max - lattice_.i_min + 1;
  for (int j = lattice_.j_min; j <= lattice_.j_max; ++j) {
    std::string row(size_t(ni), '0');
    for (int i = lattice_.i_min; i <= lattice_.i_max; ++i) row[size_t(i - lattice_.i_min)] = lattice_.is_covered(i, j) ? '1' : '0';
    covered.push_back(row);
  }
  json nodes = json::array();
  for (const auto& n : nodes_) nodes.push_back({n.x(), n.y()});
  return {{"kind", "dewarp_map"},
          {"model", dewarp_model_name(model_)},
          {"size", {width_, height_}},
          {"pitch_px", lattice_.pitch_px},
          {"lattice",
           {{"origin_px", {lattice_.origin_px.x(), lattice_.origin_px.y()}},
            {"pitch_px", lattice_.pitch_px},
            {"i_range", {lattice_.i_min, lattice_.i_max}},
            {"j_range", {lattice_.j_min, lattice_.j_max}},
            {"covered", covered}}},
          {"polynomial", {{"inverse", inverse_.to_json()}, {"forward", forward_guess_.to_json()}}},
          {"bilinear", {{"nodes_px", nodes}}}};
}

DewarpMap DewarpMap::read(const std::string& path) { return from_json(read_json(path), path); }

DewarpMap DewarpMap::from_json(const nlohmann::json& j, const std::string& what) {
  using nlohmann::json;
  auto bad = [&](const std::string& problem) { throw_input_error(what, problem); };
  if (!j.is_object()) bad("expected a JSON object");
  if (j.contains("status") && j["status"] != "ok")
    bad("the fit failed (" + (j.contains("reason") && j["reason"].is_string() ? j["reason"].get<std::string>() : "no reason") + "), no map");
  if (!j.contains("kind") || j["kind"] != "dewarp_map") bad("expected \"kind\": \"dewarp_map\"");
  if (!j.contains("model") || !j["model"].is_string()) bad("missing \"model\"");
  const DewarpModel model = j["model"] == "polynomial" ? DewarpModel::polynomial
                            : j["model"] == "bilinear" ? DewarpModel::bilinear
                                                       : (bad("\"model\" must be polynomial or bilinear"), DewarpModel::polynomial);
  auto number = [&](const json& v, const std::string& name) {
    if (!v.is_number() || !std::isfinite(v.get<double>())) bad("\"" + name + "\" must be a finite number");
    return v.get<double>();
  };
  auto pair = [&](const json& v, const std::string& name) {
    if (!v.is_array() || v.size() != 2) bad("\"" + name + "\" must be a pair of numbers");
    return Eigen::Vector2d(number(v[0], name), number(v[1], name));
  };
  const Eigen::Vector2d size = pair(j.value("size", json()), "size");
  if (size.x() < 1 || size.y() < 1 || size.x() > 65536 || size.y() > 65536 || size != size.array().round().matrix())
    bad("\"size\" must be two positive integers");
  if (!j.contains("lattice") || !j["lattice"].is_object()) bad("missing \"lattice\"");
  const json& l = j["lattice"];
  DewarpLattice lat;
  lat.origin_px = pair(l.value("origin_px", json()), "lattice.origin_px");
  lat.pitch_px = number(l.value("pitch_px", json()), "lattice.pitch_px");
  if (!(lat.pitch_px > 0)) bad("\"lattice.pitch_px\" must be positive");
  const Eigen::Vector2d ir = pair(l.value("i_range", json()), "lattice.i_range"), jr = pair(l.value("j_range", json()), "lattice.j_range");
  // Checked as doubles first: a cast of 1e300 to int is undefined.
  for (double r : {ir.x(), ir.y(), jr.x(), jr.y()})
    if (std::abs(r) > 1e5 || r != std::round(r)) bad("bad lattice ranges");
  lat.i_min = int(ir.x()), lat.i_max = int(ir.y()), lat.j_min = int(jr.x()), lat.j_max = int(jr.y());
  if (lat.i_max < lat.i_min || lat.j_max < lat.j_min || lat.i_max - lat.i_min > 10000 || lat.j_max - lat.j_min > 10000)
    bad("bad lattice ranges");
  const int ni = lat.i_max - lat.i_min + 1, nj = lat.j_max - lat.j_min + 1;
  const json& cov = l.value("covered", json());
  if (!cov.is_array() || int(cov.size()) != nj) bad("\"lattice.covered\" must have one string per lattice row");
  for (const auto& row : cov) {
    if (!row.is_string() || int(row.get<std::string>().size()) != ni) bad("\"lattice.covered\" rows must be strings of the lattice's width");
    for (char ch : row.get<std::string>()) {
      if (ch != '0' && ch != '1') bad("\"lattice.covered\" holds only 0 and 1");
      lat.covered.push_back(ch == '1');
    }
  }
  if (!j.contains("polynomial") || !j["polynomial"].is_object()) bad("missing \"polynomial\"");
  const PolynomialMap2 inverse = PolynomialMap2::from_json(j["polynomial"].value("inverse", json()), what);
  const PolynomialMap2 forward = PolynomialMap2::from_json(j["polynomial"].value("forward", json()), what);
  if (!j.contains("bilinear") || !j["bilinear"].is_object()) bad("missing \"bilinear\"");
  const json& nodes = j["bilinear"].value("nodes_px", json());
  if (!nodes.is_array() || nodes.size() != size_t(ni + 2) * size_t(nj + 2)) bad("\"bilinear.nodes_px\" must hold (cols+2) x (rows+2) nodes");
  std::vector<Eigen::Vector2d> n;
  for (const auto& p : nodes) n.push_back(pair(p, "bilinear.nodes_px"));
  return DewarpMap(model, int(size.x()), int(size.y()), lat, inverse, forward, n);
}

}  // namespace fluoro
