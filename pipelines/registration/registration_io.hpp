#pragma once
// Files of the registration: user-traced contours in, the result document out.
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pipelines/registration/registration.hpp"

namespace fluoro {

// Reads {"views": [{"polylines": [[[u, v], ...], ...]}, ...]}, one entry per view in --view order
// (an entry with no polylines leaves that view to automatic contours): per view, its polylines.
// Throws InputError naming the file for a malformed document, a view count other than
// `widths.size()`, or a point outside its image.
using Polyline = std::vector<Eigen::Vector2f>;
std::vector<std::vector<Polyline>> read_contour_polylines(const std::string& path, const std::vector<int>& widths,
                                                          const std::vector<int>& heights);

// A polyline's points at one-pixel spacing along its straight segments.
std::vector<Eigen::Vector2f> sample_polyline(const Polyline& line);

// read_contour_polylines, each polyline sampled (sample_polyline) and a view's put together.
std::vector<std::vector<Eigen::Vector2f>> read_contours(const std::string& path, const std::vector<int>& widths,
                                                        const std::vector<int>& heights);

// The result document (docs/cli.md): T_world_ct, status, confidence, score, per-stage timings.
nlohmann::json report_to_json(const RegistrationReport& report);
// The confidence test's ingredients: {"min_view_sharpness", "required_view_sharpness", "sharp",
// "views": [{"correlation", "displaced_correlation", "simulated_displaced", "sharpness"}, ...],
// "seconds"} (docs/cli.md).
nlohmann::json peak_sharpness_to_json(const PeakSharpness& p);
// The per-view gradient correlations as "0.61/0.66/0.68" (two decimals, --view order).
std::string format_view_correlations(const RegistrationReport& report);

}  // namespace fluoro
