#pragma once
// PANO.json (shared/docs/FORMATS.md "Panorama") and C.json as `fluoro panorama` and the Python
// module both read and write them: one place, so the two cannot drift apart.
#include <Eigen/Core>
#include <array>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "pipelines/panorama/panorama.hpp"

namespace fluoro {

// "max" | "mean" | "median" | "min"; InputError naming `what` otherwise.
PanoramaBlend parse_panorama_blend(const std::string& s, const std::string& what);

// C.json: {"frames": [i, i+1], "polylines": [[[u, v], ...], [[u, v], ...]]} in the original frames'
// pixels; `what` names it in errors. `correct` maps such a pixel to the corrected frame (identity
// without a dewarp; the dewarp's correct_point plugs in here) and returns nullopt outside its field of view.
PlaneContours plane_contours_from_json(const nlohmann::json& j, const std::string& what, int frames, int width, int height,
                                       const std::function<std::optional<Eigen::Vector2d>(const Eigen::Vector2d&)>& correct);

// The report without inputs, provenance and timings: "status" is "failed" with a "reason" (the first
// unaligned frame, named by `files`) when the reference frame or, unless allow_partial, any frame
// is unaligned, or the contours' plane was not found; "partial" tells whether frames were left out.
nlohmann::json panorama_document(const Panorama& p, const std::vector<std::string>& files, double graduation_mm,
                                 const std::string& blend, const std::string& dewarp, bool contours_given,
                                 bool allow_partial);

// `fluoro measure`'s checks of a PANO.json report named `what`: an object, status "ok", a positive
// "mm_per_pixel", a "size" [width, height] and, when there, a "plane" of "ruler" or "contours".
// Returns {mm_per_pixel, width, height}.
std::array<double, 3> check_panorama_report(const nlohmann::json& report, const std::string& what);

// The distance between panorama pixels a and b (which must lie on it; `points_what` names them in
// errors), in mm in the report's plane, with its uncertainty (FORMATS.md "Panorama"). The
// uncertainty comes from the report's "uncertainty" section (this project's addition to PANO.json):
// without one, or null (a report from another program), it is unknown, never taken as 0; a section
// that is there must hold non-negative numbers.
struct PanoramaDistance {
  double distance_mm = 0, distance_px = 0;
  std::optional<double> uncertainty_mm;
};
PanoramaDistance measure_on_panorama(const nlohmann::json& report, const std::string& what, const Eigen::Vector2d& a,
                                     const Eigen::Vector2d& b, const std::string& points_what);

}  // namespace fluoro
