// The fit. The corrected frame: node (0, 0) (the seed hole near the centre) stays where a local
// affine fit of the holes around it puts it, the lattice axes become the image axes and the pitch is
// the local mean pitch there (sqrt of the affine's determinant), so the corrected image resembles
// the input near its centre. Holes are then fitted in that frame.
#include "pipelines/calibration/dewarp_fit.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <map>

#include "engine/median.hpp"
#include "pipelines/calibration/hole_detection.hpp"
#include "pipelines/calibration/lattice_pairing.hpp"

namespace fluoro {
namespace {

// A hole partly under an occluder or cut by the FOV edge keeps a biased centroid: its integrated
// contrast falls short of its lattice neighbours' (compared locally: a real field's contrast drifts
// with the intensifier's gain and scatter).
std::vector<bool> complete_holes(const std::vector<LatticeHole>& holes, const std::vector<HoleBlob>& blobs) {
  std::map<std::pair<int, int>, double> mass;
  for (const auto& h : holes) mass[{h.i, h.j}] = blobs[size_t(h.blob)].mass;
  std::vector<bool> keep(holes.size(), true);
  for (size_t k = 0; k < holes.size(); ++k) {
    std::vector<double> around;
    for (int dj = -2; dj <= 2; ++dj)
      for (int di = -2; di <= 2; ++di) {
        const auto it = mass.find({holes[k].i + di, holes[k].j + dj});
        if ((di || dj) && it != mass.end()) around.push_back(it->second);
      }
    if (around.size() >= 3) keep[k] = blobs[size_t(holes[k].blob)].mass > 0.8 * upper_median(around);
  }
  return keep;
}

// The polynomial's degree by 5-fold cross-validation on the holes: the lowest degree whose median
// held-out residual is within 10% of the best. Too high a degree follows the noise and swings in
// the gaps an occluder leaves and in the ring outside the last holes; too low cannot bend enough.
int choose_degree(const std::vector<Eigen::Vector2d>& from, const std::vector<Eigen::Vector2d>& to, int max_degree,
                  const Eigen::Vector2d& centre, double scale) {
  const int n = int(from.size());
  std::vector<std::pair<int, double>> scores;
  for (int d = 2; d <= std::min(max_degree, 15) && PolynomialMap2::term_count(d) * 4 <= n * 4 / 5; ++d) {
    std::vector<double> held_out;
    for (int fold = 0; fold < 5; ++fold) {
      std::vector<Eigen::Vector2d> f, t;
      for (int k = 0; k < n; ++k)
        if ((k * 7) % 5 != fold) f.push_back(from[size_t(k)]), t.push_back(to[size_t(k)]);
      const PolynomialMap2 m = PolynomialMap2::fit(f, t, d, centre, scale);
      for (int k = 0; k < n; ++k)
        if ((k * 7) % 5 == fold) held_out.push_back((m(from[size_t(k)]) - to[size_t(k)]).norm());
    }
    scores.push_back({d, upper_median(held_out)});
  }
  if (scores.empty()) return 1;
  double best = scores[0].second;
  for (const auto& [d, e] : scores) best = std::min(best, e);
  for (const auto& [d, e] : scores)
    if (e <= 1.1 * best) return d;
  return scores.back().first;
}

}  // namespace

nlohmann::json dewarp_fit_document(const DewarpFit& fit, const GridModel& grid, int width, int height) {
  nlohmann::json doc = fit.ok ? fit.map->to_json() : nlohmann::json::object();
  doc["status"] = fit.ok ? "ok" : "failed";
  if (!fit.ok) doc["reason"] = fit.reason;
  doc["size"] = {width, height};
  doc["holes_found"] = fit.holes_found;
  doc["holes_used"] = fit.holes_used;
  if (fit.ok) {
    doc["residual_px"] = {{"mean", fit.residual_mean_px}, {"max", fit.residual_max_px}};
    doc["visible_fraction"] = fit.visible_fraction;
    doc["plate_mm_per_px"] = grid.pitch_mm / fit.map->pitch_px();
  }
  return doc;
}

DewarpFit fit_dewarp(const Image& image, const GridModel& grid, const DewarpFitOptions& options) {
  DewarpFit fit;
  const HoleDetection det = detect_holes(image);
  fit.holes_found = int(det.blobs.size());
  auto fail = [&](const std::string& reason) {
    fit.ok = false;
    fit.reason = reason;
    return fit;
  };
  if (det.blobs.size() < 5) return fail("no holes found (" + std::to_string(det.blobs.size()) + " hole-like blobs)");

  std::vector<Eigen::Vector2d> centres;
  for (const auto& b : det.blobs) centres.push_back(b.centre_px);
  const Eigen::Vector2d image_centre(0.5 * (image.width - 1), 0.5 * (image.height - 1));
  std::vector<LatticeHole> paired = pair_lattice(centres, image_centre);
  if (paired.size() < 9) return fail("no square lattice of holes found (" + std::to_string(paired.size()) + " holes indexed)");

  const std::vector<bool> complete = complete_holes(paired, det.blobs);
  std::vector<LatticeHole> used;
  for (size_t k = 0; k < paired.size(); ++k)
    if (complete[k]) used.push_back(paired[k]);

  Eigen::Matrix2d A;
  Eigen::Vector2d origin;
  if (!local_lattice_affine(used, centres, 0, 0, 3, A, origin)) return fail("too few holes around the centre to set the frame");
  DewarpLattice lat;
  lat.pitch_px = std::sqrt(std::abs(A.determinant()));
  lat.origin_px = origin;
  const double expected_diameter = grid.hole_diameter_mm / grid.pitch_mm * lat.pitch_px;
  if (det.typical_diameter_px < 0.4 * expected_diameter || det.typical_diameter_px > 2.0 * expected_diameter)
    return fail("the blobs (" + std::to_string(det.typical_diameter_px) + " px wide) do not match the grid's holes (about " +
                std::to_string(expected_diameter) + " px at a pitch of " + std::to_string(lat.pitch_px) + " px)");
  auto corrected_of = [&](const LatticeHole& h) { return Eigen::Vector2d(lat.origin_px + lat.pitch_px * Eigen::Vector2d(h.i, h.j)); };

  // Robust least squares: refit without holes far off the smooth field (dust that fell on a node,
  // a cut hole the contrast test missed) until nothing changes.
  const Eigen::Vector2d centre = image_centre;
  const double scale = 0.5 * std::max(image.width, image.height);
  PolynomialMap2 inverse;
  std::vector<double> residuals;
  int degree = 0;
  auto refit = [&](bool choose) {
    std::vector<Eigen::Vector2d> from, to;
    for (const auto& h : used) from.push_back(corrected_of(h)), to.push_back(centres[size_t(h.blob)]);
    if (choose) degree = choose_degree(from, to, options.max_degree, centre, scale);
    inverse = PolynomialMap2::fit(from, to, degree, centre, scale);
    residuals.clear();
    for (size_t k = 0; k < used.size(); ++k) residuals.push_back((inverse(from[k]) - to[k]).norm());
  };
  for (int round = 0; round < 8 && used.size() >= 16; ++round) {
    refit(round == 0);  // the cross-validation's median shrugs off the outliers of the first round
    const double limit = std::max(4.0 * upper_median(residuals), 0.02);
    std::vector<LatticeHole> kept;
    for (size_t k = 0; k < used.size(); ++k)
      if (residuals[k] <= limit) kept.push_back(used[k]);
    if (kept.size() == used.size()) break;
    used = kept;
  }
  if (used.size() >= 16) refit(true);  // the degree again, on the clean holes
  fit.holes_used = int(used.size());
  // Holes the field of view could show: its illuminated area over one lattice cell's, and never more
  // than the plate has (a plate smaller than the field of view shows all of its holes).
  const double possible =
      std::min(det.illuminated_area_px / (lat.pitch_px * lat.pitch_px), double(grid.rows) * double(grid.cols));
  fit.visible_fraction = possible > 0 ? std::min(1.0, used.size() / possible) : 0;
  if (used.size() < 16 || fit.visible_fraction < options.min_visible_fraction)
    return fail("only " + std::to_string(used.size()) + " usable holes, " + std::to_string(int(std::round(100 * fit.visible_fraction))) +
                "% of the about " + std::to_string(int(std::round(possible))) + " the field of view holds (at least " +
                std::to_string(int(std::round(100 * options.min_visible_fraction))) + "% needed)");
  double sum = 0;
  for (double r : residuals) sum += r, fit.residual_max_px = std::max(fit.residual_max_px, r);
  fit.residual_mean_px = sum / double(residuals.size());

  std::vector<Eigen::Vector2d> from, to;
  lat.i_min = lat.i_max = used[0].i, lat.j_min = lat.j_max = used[0].j;
  for (const auto& h : used) {
    from.push_back(centres[size_t(h.blob)]), to.push_back(corrected_of(h));
    lat.i_min = std::min(lat.i_min, h.i), lat.i_max = std::max(lat.i_max, h.i);
    lat.j_min = std::min(lat.j_min, h.j), lat.j_max = std::max(lat.j_max, h.j);
  }
  const PolynomialMap2 forward = PolynomialMap2::fit(from, to, inverse.degree(), centre, scale);

  // Covered nodes: used holes, and nodes enclosed by used holes along their row or their column (an
  // occluder's band across the grid stays in the field of view; for the intensifier's convex field
  // the outside does not grow).
  const int ni = lat.i_max - lat.i_min + 1, nj = lat.j_max - lat.j_min + 1;
  std::vector<uint8_t> is_used(size_t(ni) * size_t(nj), 0);
  std::map<std::pair<int, int>, int> used_blob;
  for (const auto& h : used) is_used[size_t(h.j - lat.j_min) * size_t(ni) + size_t(h.i - lat.i_min)] = 1, used_blob[{h.i, h.j}] = h.blob;
  std::vector<int> row_lo(size_t(nj), ni), row_hi(size_t(nj), -1), col_lo(size_t(ni), nj), col_hi(size_t(ni), -1);
  for (int j = 0; j < nj; ++j)
    for (int i = 0; i < ni; ++i)
      if (is_used[size_t(j) * size_t(ni) + size_t(i)]) {
        row_lo[size_t(j)] = std::min(row_lo[size_t(j)], i), row_hi[size_t(j)] = std::max(row_hi[size_t(j)], i);
        col_lo[size_t(i)] = std::min(col_lo[size_t(i)], j), col_hi[size_t(i)] = std::max(col_hi[size_t(i)], j);
      }
  lat.covered.assign(is_used.size(), 0);
  for (int j = 0; j < nj; ++j)
    for (int i = 0; i < ni; ++i)
      lat.covered[size_t(j) * size_t(ni) + size_t(i)] =
          (i >= row_lo[size_t(j)] && i <= row_hi[size_t(j)]) || (j >= col_lo[size_t(i)] && j <= col_hi[size_t(i)]);

  // Bilinear nodes: the found centre where a hole was used, the polynomial elsewhere (hidden holes
  // and the ring one pitch outside), so every cell of the field of view has four corners.
  std::vector<Eigen::Vector2d> nodes;
  for (int j = lat.j_min - 1; j <= lat.j_max + 1; ++j)
    for (int i = lat.i_min - 1; i <= lat.i_max + 1; ++i) {
      const auto it = used_blob.find({i, j});
      nodes.push_back(it != used_blob.end() ? centres[size_t(it->second)]
                                            : inverse(Eigen::Vector2d(lat.origin_px + lat.pitch_px * Eigen::Vector2d(i, j))));
    }

  std::vector<bool> is_used_blob(det.blobs.size(), false);
  for (const auto& h : used) is_used_blob[size_t(h.blob)] = true;
  for (size_t k = 0; k < det.blobs.size(); ++k) (is_used_blob[k] ? fit.used_px : fit.rejected_px).push_back(centres[k]);
  fit.map.emplace(options.model, image.width, image.height, lat, inverse, forward, nodes);
  fit.ok = true;
  return fit;
}

}  // namespace fluoro
