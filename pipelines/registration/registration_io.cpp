#include "pipelines/registration/registration_io.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "engine/error.hpp"
#include "engine/json_io.hpp"

namespace fluoro {

std::vector<std::vector<Polyline>> read_contour_polylines(const std::string& path, const std::vector<int>& widths,
                                                          const std::vector<int>& heights) {
  const nlohmann::json doc = read_json(path);
  if (!doc.is_object() || !doc.contains("views") || !doc["views"].is_array())
    throw_input_error(path, "expected {\"views\": [{\"polylines\": [...]}, ...]}");
  if (doc["views"].size() != widths.size())
    throw_input_error(path, std::to_string(doc["views"].size()) + " views of contours for " +
                                std::to_string(widths.size()) + " X-rays");
  std::vector<std::vector<Polyline>> out(widths.size());
  for (size_t v = 0; v < widths.size(); ++v) {
    const auto& view = doc["views"][v];
    const std::string at = "view " + std::to_string(v + 1);
    if (!view.is_object()) throw_input_error(path, at + ": expected {\"polylines\": [...]}");
    if (!view.contains("polylines")) continue;
    if (!view["polylines"].is_array()) throw_input_error(path, at + ": \"polylines\" must be an array");
    for (const auto& line : view["polylines"]) {
      if (!line.is_array()) throw_input_error(path, at + ": a polyline must be an array of [u, v]");
      std::vector<Eigen::Vector2f> points;
      for (const auto& p : line) {
        if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number())
          throw_input_error(path, at + ": a polyline point must be [u, v]");
        const Eigen::Vector2f q(p[0].get<float>(), p[1].get<float>());
        if (!(q.x() >= 0 && q.y() >= 0 && q.x() <= float(widths[v] - 1) && q.y() <= float(heights[v] - 1)))
          throw_input_error(path, at + ": point (" + std::to_string(q.x()) + ", " + std::to_string(q.y()) +
                                      ") lies outside the " + std::to_string(widths[v]) + "x" +
                                      std::to_string(heights[v]) + " image");
        points.push_back(q);
      }
      if (!points.empty()) out[v].push_back(std::move(points));
    }
  }
  return out;
}

std::vector<Eigen::Vector2f> sample_polyline(const Polyline& points) {
  std::vector<Eigen::Vector2f> out;
  for (size_t i = 0; i + 1 < points.size(); ++i) {
    const int n = std::max(1, int(std::ceil((points[i + 1] - points[i]).norm())));
    for (int k = 0; k < n; ++k) out.push_back(points[i] + (points[i + 1] - points[i]) * (float(k) / float(n)));
  }
  if (!points.empty()) out.push_back(points.back());
  return out;
}

std::vector<std::vector<Eigen::Vector2f>> read_contours(const std::string& path, const std::vector<int>& widths,
                                                        const std::vector<int>& heights) {
  std::vector<std::vector<Eigen::Vector2f>> out;
  for (const auto& view : read_contour_polylines(path, widths, heights)) {
    out.emplace_back();
    for (const Polyline& line : view)
      for (const auto& p : sample_polyline(line)) out.back().push_back(p);
  }
  return out;
}

nlohmann::json report_to_json(const RegistrationReport& r) {
  nlohmann::json stages = nlohmann::json::array();
  for (const StageReport& s : r.stages)
    stages.push_back({{"name", s.name},
                      {"seconds", s.seconds},
                      {"iterations", s.iterations},
                      {"evaluations", s.evaluations},
                      {s.name.ends_with("coarse") ? "rms_ray_distance_mm" : "score", s.value},
                      {"converged", s.converged}});
  nlohmann::json j;
  j["status"] = r.ok ? "ok" : "failed";
  if (!r.ok) j["reason"] = r.failure_reason;
  j["T_world_ct"] = pose_to_json(r.pose)["T_world_ct"];
  j["initial_T_world_ct"] = pose_to_json(r.initial)["T_world_ct"];
  j["score"] = r.score;
  j["gradient_correlation"] = r.gradient_correlation;
  j["view_gradient_correlations"] = r.view_correlations;
  j["confident"] = r.confident;
  // Whether the coarse step's global search ran, and whether the result is the retry a doubtful
  // first result got (RegistrationOptions::global_search_when_doubtful).
  j["global_search"] = {{"ran", r.global_search_ran},
                         {"retried_when_doubtful", r.retried_when_doubtful},
                         {"result_from_retry", r.result_from_retry}};
  j["confidence"] = {{"rule", "peak_sharpness"},
                     {"peak_sharpness", peak_sharpness_to_json(r.peak_sharpness)},
                     {"gpr_pose_sharp", r.gpr_pose_sharp},
                     {"correlation_floor", r.correlation_floor},
                     {"correlation_floor_met", r.ok && r.correlation_floor_met()},
                     {"expected_correlation", r.expected_correlation},
                     {"expected_view_correlations", r.expected_view_correlations},
                     {"relative_view_correlations", r.relative_view_correlations()},
                     {"relative_correlation", r.relative_correlation()},
                     {"relative_correlation_floor", r.relative_correlation_floor},
                     {"relative_correlation_floor_met", r.ok && r.relative_correlation_floor_met()},
                     {"correlation_thresholds_met", r.correlation_thresholds_met}};
  if (r.ok && !r.confident) {
    // Every test the result failed, in the order the rule takes them.
    std::vector<std::string> reasons;
    if (!r.peak_sharpness.sharp) {
      std::string sharpness, offsets;
      for (size_t v = 0; v < r.peak_sharpness.views.size(); ++v) {
        char s[64];
        std::snprintf(s, sizeof s, "%s%.2f", v ? "/" : "", r.peak_sharpness.views[v].sharpness);
        sharpness += s;
        std::snprintf(s, sizeof s, "%s%.2f", v ? "/" : "", r.peak_sharpness.views[v].peak_offset);
        offsets += s;
      }
      reasons.push_back("the result is not, in every view, the sharp maximum of the gradient correlation that a right "
                        "pose is (sharpness per view " + sharpness + ", peak offset " + offsets + " mm or degrees)");
    }
    if (!r.gpr_pose_sharp)
      reasons.push_back("the GPR's pose before the correlation polish is not sharp in every view");
    if (!r.correlation_floor_met()) {
      char s[128];
      std::snprintf(s, sizeof s, "the mean gradient correlation %.3f is under the floor %g set for it",
                    r.gradient_correlation, r.correlation_floor);
      reasons.push_back(s);
    }
    if (!r.relative_correlation_floor_met()) {
      const std::vector<double> rel = r.relative_view_correlations();
      const size_t v = size_t(std::min_element(rel.begin(), rel.end()) - rel.begin());
      char s[224];
      if (rel.empty())
        std::snprintf(s, sizeof s, "no view's expected correlation was measured for the relative floor %g",
                      r.relative_correlation_floor);
      else
        std::snprintf(s, sizeof s,
                      "view %zu's (in the order given, from 1) gradient correlation %.3f is %.2f of the %.3f an X-ray of "
                      "the whole CT would reach at this pose, under the %g required",
                      v + 1, r.view_correlations[v], rel[v], r.expected_view_correlations[v], r.relative_correlation_floor);
      reasons.push_back(s);
    }
    if (reasons.empty()) reasons.push_back("the former correlation thresholds (required) are not met");
    std::string text = "likely failure: ";
    for (size_t i = 0; i < reasons.size(); ++i) text += (i ? "; " : "") + reasons[i];
    j["warning"] = text + " (correlation per view " + format_view_correlations(r) + ")";
  }
  j["stages"] = stages;
  j["seconds"] = r.seconds;
  return j;
}

nlohmann::json peak_sharpness_to_json(const PeakSharpness& p) {
  // An infinite peak offset (a view whose correlation does not drop) is written as null.
  auto finite = [](double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr); };
  nlohmann::json views = nlohmann::json::array();
  for (const ViewSharpness& v : p.views)
    views.push_back({{"correlation", v.correlation},
                     {"displaced_correlation", v.displaced_correlation},
                     {"simulated_displaced_correlation", v.simulated_displaced},
                     {"sharpness", v.sharpness},
                     {"peak_offset", finite(v.peak_offset)},
                     {"judged_axes", v.judged_axes}});
  const PeakSharpnessOptions& o = p.options;
  return {{"sharp", p.sharp},
          {"min_sharpness", p.min_sharpness},
          {"max_peak_offset", finite(p.max_peak_offset)},
          {"required_sharpness", o.min_axis_sharpness},
          {"allowed_peak_offset", o.max_peak_offset},
          {"displacement_deg", o.rotation_deg},
          {"displacement_mm", o.translation_mm},
          {"views", views},
          {"seconds", p.seconds}};
}

std::string format_view_correlations(const RegistrationReport& r) {
  std::string out;
  for (size_t v = 0; v < r.view_correlations.size(); ++v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%s%.2f", v ? "/" : "", r.view_correlations[v]);
    out += buf;
  }
  return out;
}

}  // namespace fluoro
