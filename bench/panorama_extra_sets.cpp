// The generator's sets beyond the goal table (docs/panorama.md, "Beyond the goal sets"): seeds
// 31-45 at the six ruler offsets, 90 sets. Every frame's placement on the ruler's plane is checked
// against the true cameras: the rule is that a frame is either placed (within 1 px) or reported
// unaligned, never misplaced - also for the frames of a refused set, which `--allow-partial`
// would compose. `fluoro_panorama_bench --extra` runs all of them; `--extra OFFSET SEED` one set,
// with each unaligned frame's reason; `--extra OFFSET SEED PIXELS` renders it at PIXELS^2.
#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "bench/panorama_goal_sets.hpp"
#include "bench/panorama_frames.hpp"
#include "datasets/panorama_scene.hpp"
#include "pipelines/panorama/panorama.hpp"

namespace fluoro {
namespace {

// Per frame: its distance from the truth on the ruler's plane (px), negative when unaligned.
std::vector<double> placement_errors(const PanoramaScene& s, const Panorama& p) {
  const Eigen::Vector2d c = 0.5 * Eigen::Vector2d(s.images[0].width - 1, s.images[0].height - 1);
  const auto at = [&](size_t i) -> Eigen::Vector2d {
    return (p.frames[i].H_panorama_frame * Eigen::Vector3d(c.x(), c.y(), 1)).head<2>();
  };
  const double k = s.focal_px / s.ruler_plane_mm;
  std::vector<double> e(s.images.size(), -1);
  if (!p.frames[0].aligned) return e;
  e[0] = 0;
  for (size_t i = 1; i < s.images.size(); ++i) {
    if (!p.frames[i].aligned) continue;
    const Eigen::Vector3d dC = s.cameras[i].source() - s.cameras[0].source();
    const Eigen::Vector2d truth = k * (Eigen::Rotation2Dd(s.rotation_deg[0] * M_PI / 180) * dC.head<2>());
    e[i] = (at(i) - at(0) - truth).norm();
  }
  return e;
}

}  // namespace

int run_extra_sets(int argc, char** argv) {
  std::vector<std::pair<double, uint32_t>> sets;
  if (argc >= 4) {
    sets.emplace_back(std::atof(argv[2]), uint32_t(std::atoi(argv[3])));
  } else {
    for (const double offset : kGoalRulerOffsetsMm)
      for (uint32_t seed = 31; seed <= 45; ++seed) sets.emplace_back(offset, seed);
  }
  int composed = 0, refused = 0, misplaced_sets = 0;
  double worst_composed = 0, worst_any = 0;
  for (const auto& [offset, seed] : sets) {
    PanoramaSceneParams params = goal_set_params(offset, seed);
    if (argc >= 5) params.pixels = std::atoi(argv[4]);
    const PanoramaScene s = make_panorama_scene(params);
    const Panorama p = align_panorama(frames_of(s), {}, std::nullopt);
    const std::vector<double> e = placement_errors(s, p);
    double worst = 0;
    int aligned = 0, misplaced = 0;
    std::string per_frame;
    for (size_t i = 0; i < e.size(); ++i) {
      char b[32];
      std::snprintf(b, sizeof b, e[i] < 0 ? " -" : " %.2f", e[i]);
      per_frame += b;
      if (e[i] < 0) continue;
      ++aligned;
      worst = std::max(worst, e[i]);
      misplaced += e[i] > 1.0;
    }
    const bool ok = p.failure.empty();
    (ok ? composed : refused) += 1;
    misplaced_sets += misplaced > 0;
    if (ok) worst_composed = std::max(worst_composed, worst);
    worst_any = std::max(worst_any, worst);
    std::printf("%+4.0f / %u: %s, %d of %zu frames aligned, worst %.2f px%s |%s\n", offset, seed, ok ? "ok" : "refused",
                aligned, e.size(), worst, misplaced ? " MISPLACED" : "", per_frame.c_str());
    if (!ok) std::printf("      %s\n", p.failure.c_str());
    if (sets.size() == 1)
      for (size_t i = 0; i < e.size(); ++i)
        if (!p.frames[i].aligned) std::printf("      frame %zu: %s\n", i, p.frames[i].problem.c_str());
    std::fflush(stdout);
  }
  std::printf("\n%d sets: %d composed, %d refused; worst placement of a frame reported aligned: %.2f px in the composed "
              "sets, %.2f px in all (allow-partial); sets with a frame aligned > 1 px off: %d\n",
              int(sets.size()), composed, refused, worst_composed, worst_any, misplaced_sets);
  return 0;
}

}  // namespace fluoro
