// PANO.json and C.json, shared by `fluoro panorama` and the Python module (panorama_document.hpp).
#include "pipelines/panorama/panorama_document.hpp"

#include <algorithm>
#include <cmath>

#include "engine/error.hpp"

namespace fluoro {

namespace {

nlohmann::json matrix_json(const Eigen::Matrix3d& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2)});
  return rows;
}

}  // namespace

PlaneContours plane_contours_from_json(const nlohmann::json& j, const std::string& what, int frames, int width, int height,
                                       const std::function<std::optional<Eigen::Vector2d>(const Eigen::Vector2d&)>& correct) {
  if (!j.is_object() || !j.contains("frames") || !j["frames"].is_array() || j["frames"].size() != 2 ||
      !j["frames"][0].is_number_integer() || !j["frames"][1].is_number_integer())
    throw_input_error(what, "\"frames\" must be two frame indices [i, i+1]");
  const int a = j["frames"][0].get<int>(), b = j["frames"][1].get<int>();
  if (a < 0 || b >= frames || b != a + 1)
    throw_input_error(what, "\"frames\" [" + std::to_string(a) + ", " + std::to_string(b) +
                                "] must be two consecutive frames among the " + std::to_string(frames) + " given");
  if (!j.contains("polylines") || !j["polylines"].is_array() || j["polylines"].size() != 2)
    throw_input_error(what, "\"polylines\" must hold two polylines, one per frame");
  PlaneContours c;
  c.first = a;
  for (int k = 0; k < 2; ++k) {
    const auto& line = j["polylines"][size_t(k)];
    if (!line.is_array() || line.size() < 2) throw_input_error(what, "each polyline needs at least 2 points");
    for (const auto& p : line) {
      if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number())
        throw_input_error(what, "a polyline point must be [u, v]");
      const Eigen::Vector2d q(p[0].get<double>(), p[1].get<double>());
      if (!q.allFinite() || q.x() < -0.5 || q.y() < -0.5 || q.x() > width - 0.5 || q.y() > height - 0.5)
        throw_input_error(what, "point (" + std::to_string(q.x()) + ", " + std::to_string(q.y()) + ") of frame " +
                                    std::to_string(a + k) + " is outside the " + std::to_string(width) + " x " +
                                    std::to_string(height) + " image");
      const auto corrected = correct(q);
      if (!corrected) throw_input_error(what, "a polyline point is outside the dewarp's field of view");
      c.polylines[k].push_back(*corrected);
    }
  }
  return c;
}

PanoramaBlend parse_panorama_blend(const std::string& s, const std::string& what) {
  if (s == "max") return PanoramaBlend::Max;
  if (s == "mean") return PanoramaBlend::Mean;
  if (s == "median") return PanoramaBlend::Median;
  if (s == "min") return PanoramaBlend::Min;
  throw_input_error(what, "must be max, mean, median or min, not " + s);
}

nlohmann::json panorama_document(const Panorama& p, const std::vector<std::string>& files, double graduation_mm,
                                 const std::string& blend, const std::string& dewarp, bool contours_given,
                                 bool allow_partial) {
  // The first frame that could not be aligned names the failure (FORMATS.md: never placed by guess).
  std::string reason;
  bool frames_missing = false;
  for (size_t i = 0; i < p.frames.size(); ++i)
    if (!p.frames[i].aligned) {
      frames_missing = true;
      if (reason.empty())
        reason = "frame " + std::to_string(i) + " (" + files[i] + ") cannot be aligned: " + p.frames[i].problem;
    }
  const bool reference_missing = !p.frames[0].aligned;
  // Contours given but their plane not found (their frames unaligned, or no crossing points).
  const bool contour_problem = contours_given && p.plane != "contours";
  if (reason.empty()) reason = p.failure;
  const bool failed = reference_missing || p.width <= 0 || (frames_missing && !allow_partial) || contour_problem;
  nlohmann::json doc;
  doc["status"] = failed ? "failed" : "ok";
  if (failed) doc["reason"] = reason;
  doc["size"] = {p.width, p.height};
  doc["mm_per_pixel"] = p.mm_per_pixel;
  doc["plane"] = p.plane;
  doc["graduation_mm"] = graduation_mm;
  doc["blend"] = blend;
  doc["dewarp"] = dewarp.empty() ? nlohmann::json(nullptr) : nlohmann::json(dewarp);
  doc["partial"] = frames_missing;
  doc["ruler_mm_per_pixel"] = p.ruler_mm_per_pixel;
  doc["plane_scale"] = p.plane_scale;
  doc["uncertainty"] = {{"scale_relative", p.scale_relative_sigma},
                        {"position_px", std::max(p.position_sigma_px, p.alignment_rms_px)},
                        {"alignment_rms_px", p.alignment_rms_px}};
  nlohmann::json jf = nlohmann::json::array();
  for (size_t i = 0; i < p.frames.size(); ++i) {
    const PanoramaFrame& f = p.frames[i];
    nlohmann::json e;
    e["file"] = files[i];
    e["aligned"] = f.aligned;
    e["confidence"] = f.confidence;
    e["overlap"] = f.overlap ? nlohmann::json(*f.overlap) : nlohmann::json(nullptr);
    e["H_panorama_frame"] = f.aligned ? matrix_json(f.H_panorama_frame) : nlohmann::json(nullptr);
    e["rotation_deg"] = f.rotation_deg;
    e["graduations"] = f.graduations;
    if (!f.aligned) e["problem"] = f.problem;
    jf.push_back(e);
  }
  doc["frames"] = jf;
  return doc;
}

namespace {

double number_at(const nlohmann::json& j, const std::string& key, const std::string& path) {
  if (!j.contains(key) || !j[key].is_number() || !std::isfinite(j[key].get<double>()))
    throw_input_error(path, "\"" + key + "\" must be a number");
  return j[key].get<double>();
}

}  // namespace

std::array<double, 3> check_panorama_report(const nlohmann::json& report, const std::string& what) {
  if (!report.is_object()) throw_input_error(what, "not a panorama report (a JSON object)");
  if (report.value("status", std::string()) != "ok")
    throw_input_error(what, "the panorama failed (status is not \"ok\"): there is nothing to measure on");
  const double mm = number_at(report, "mm_per_pixel", what);
  if (!(mm > 0)) throw_input_error(what, "\"mm_per_pixel\" must be positive");
  if (report.contains("plane") && report["plane"] != "ruler" && report["plane"] != "contours")
    throw_input_error(what, "\"plane\" must be \"ruler\" or \"contours\"");
  if (!report.contains("size") || !report["size"].is_array() || report["size"].size() != 2 ||
      !report["size"][0].is_number() || !report["size"][1].is_number())
    throw_input_error(what, "\"size\" must be [width, height]");
  return {mm, report["size"][0].get<double>(), report["size"][1].get<double>()};
}

PanoramaDistance measure_on_panorama(const nlohmann::json& report, const std::string& what, const Eigen::Vector2d& a,
                                     const Eigen::Vector2d& b, const std::string& points_what) {
  const auto [mm, w, h] = check_panorama_report(report, what);
  const double q[4] = {a.x(), a.y(), b.x(), b.y()};
  for (int k = 0; k < 4; ++k)
    if (!std::isfinite(q[k]) || q[k] < -0.5 || q[k] > (k % 2 ? h : w) - 0.5)
      throw_input_error(points_what, "a point lies outside the " + std::to_string(int(w)) + " x " +
                                         std::to_string(int(h)) + " panorama");
  const double px = std::hypot(q[2] - q[0], q[3] - q[1]);
  const double d = px * mm;
  // Uncertainty: the scale's relative error over the whole distance, plus each end's placement
  // error (a frame's position along the ruler, or the adjustment's residual) in quadrature.
  if (!report.contains("uncertainty") || report["uncertainty"].is_null()) return {d, px, std::nullopt};
  const nlohmann::json& un = report["uncertainty"];
  if (!un.is_object()) throw_input_error(what, "\"uncertainty\" must be an object");
  double value[2];
  const char* keys[2] = {"scale_relative", "position_px"};
  for (int k = 0; k < 2; ++k) {
    if (!un.contains(keys[k]) || !un[keys[k]].is_number() || !std::isfinite(un[keys[k]].get<double>()) ||
        un[keys[k]].get<double>() < 0)
      throw_input_error(what, std::string("\"uncertainty.") + keys[k] + "\" must be a non-negative number");
    value[k] = un[keys[k]].get<double>();
  }
  const double rel = value[0], pos = value[1];
  return {d, px, std::sqrt(std::pow(d * rel, 2) + 2 * std::pow(pos * mm, 2))};
}

}  // namespace fluoro
