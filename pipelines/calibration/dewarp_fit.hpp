#pragma once
// Fitting a dewarp map to a grid X-ray: detect the holes, index them on the lattice, drop holes
// that are cut or off the smooth field, fit both map models, judge whether enough of the grid showed.
#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "engine/grid_model.hpp"
#include "engine/image.hpp"
#include "pipelines/calibration/dewarp_map.hpp"

namespace fluoro {

// The model `apply` will use, the polynomial's highest degree, and how much of the grid must show.
struct DewarpFitOptions {
  DewarpModel model = DewarpModel::polynomial;
  int max_degree = 7;                 // of the global polynomial (lowered when holes are few)
  double min_visible_fraction = 0.3;  // used holes / holes the field of view could show
};

// The outcome: a map when ok, otherwise the reason; the diagnostics either way.
struct DewarpFit {
  bool ok = false;
  std::string reason;
  int holes_found = 0, holes_used = 0;
  double visible_fraction = 0;
  double residual_mean_px = 0, residual_max_px = 0;  // of the global polynomial at the used holes
  std::vector<Eigen::Vector2d> used_px, rejected_px;  // found centres, for the overlay
  std::optional<DewarpMap> map;
};

// `grid` gives the hole-to-pitch ratio only: the plate's lattice is symmetric, so which hole is
// which does not matter. Never throws for a readable image; failures come back with a reason.
DewarpFit fit_dewarp(const Image& image, const GridModel& grid, const DewarpFitOptions& options = {});

// MAP.json without `inputs` and timings (shared/docs/FORMATS.md): the map's own keys when the fit
// succeeded, `status` (and `reason`), `size` (the fitted image's), `holes_found`, `holes_used`,
// `residual_px`, `visible_fraction`, `plate_mm_per_px`.
nlohmann::json dewarp_fit_document(const DewarpFit& fit, const GridModel& grid, int width, int height);

}  // namespace fluoro
