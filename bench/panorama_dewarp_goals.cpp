// The goal table of docs/panorama.md through a distortion: every frame of each goal set bent by an
// image intensifier's distortion (the 512^2 grid scene of seed 1, 6 px at the field's edge) and
// corrected with the map fitted to that scene's grid image, the contour traced on the bent frames
// and corrected by the map, the landmarks likewise; as `fluoro panorama --dewarp` does.
#include <cmath>
#include <cstdio>
#include <vector>

#include "bench/panorama_goal_sets.hpp"
#include "datasets/dewarp_grid.hpp"
#include "engine/image_mat.hpp"
#include "pipelines/calibration/dewarp_fit.hpp"
#include "pipelines/panorama/panorama.hpp"

namespace fluoro {

int run_dewarp_goals() {
  DewarpSceneOptions o;
  o.size = 512;
  const DewarpScene grid = make_dewarp_scene(o);
  const DewarpFit fit = fit_dewarp(grid.image, grid.grid);
  if (!fit.ok) {
    std::printf("the grid's map could not be fitted: %s\n", fit.reason.c_str());
    return 1;
  }
  const DewarpMap& map = *fit.map;
  std::printf("| ruler - bone plane (mm) | seed | length (mm) | error through the dewarp | status |\n|---|---|---|---|---|\n");
  int composed = 0, sets = 0;
  double worst = 0;
  for (const double offset : kGoalRulerOffsetsMm)
    for (const uint32_t seed : kGoalSeeds) {
      ++sets;
      const PanoramaScene s = make_panorama_scene(goal_set_params(offset, seed));
      std::vector<cv::Mat> frames;
      for (const auto& im : s.images) {
        Image f;
        f.width = im.width, f.height = im.height;
        f.pixels.assign(im.pixels.begin(), im.pixels.end());
        const Image bent = distort_image(f, grid.distortion);
        frames.push_back(map.correct_image(mat_view(bent).clone()));
      }
      PlaneContours c;
      c.first = s.contour_first_frame;
      for (int k = 0; k < 2; ++k)
        for (const auto& q : s.contour[k])
          if (const auto p = map.correct_point(grid.distortion.distort(q))) c.polylines[k].push_back(*p);
      const Panorama p = align_panorama(frames, {}, c);
      if (!p.failure.empty() || p.plane != "contours") {
        std::printf("| %+.0f | %u | %.0f | - | failed: %s |\n", offset, seed, s.true_length_mm, p.failure.c_str());
        continue;
      }
      // Each landmark from the frame where it is nearest the centre, as the goal table.
      Eigen::Vector2d q[2];
      bool inside = true;
      for (int k = 0; k < 2; ++k) {
        const Eigen::Vector2d centre = 0.5 * Eigen::Vector2d(s.images[0].width - 1, s.images[0].height - 1);
        int f = 0;
        for (int i = 1; i < int(s.images.size()); ++i)
          if ((project_in_frame(s, i, s.landmarks[k]) - centre).norm() < (project_in_frame(s, f, s.landmarks[k]) - centre).norm()) f = i;
        const auto px = map.correct_point(grid.distortion.distort(project_in_frame(s, f, s.landmarks[k])));
        if (!px) inside = false;
        else q[k] = (p.frames[size_t(f)].H_panorama_frame * Eigen::Vector3d(px->x(), px->y(), 1)).head<2>();
      }
      if (!inside) {
        std::printf("| %+.0f | %u | %.0f | - | a landmark outside the map's field |\n", offset, seed, s.true_length_mm);
        continue;
      }
      ++composed;
      const double error = 100 * ((q[1] - q[0]).norm() * p.mm_per_pixel - s.true_length_mm) / s.true_length_mm;
      worst = std::max(worst, std::abs(error));
      std::printf("| %+.0f | %u | %.0f | %+.3f %% | ok |\n", offset, seed, s.true_length_mm, error);
    }
  std::printf("\nthrough the dewarp: %d of %d sets composed; worst length error %.3f %% (goal 0.5 %%)\n", composed, sets, worst);
  return 0;
}

}  // namespace fluoro
