#pragma once
// The generated sets of docs/panorama.md's goal table (fluoro_panorama_bench --goals), shared with
// the cv::Stitcher comparison (--stitcher) so that both run on exactly the same frames.
#include <cstdint>

#include "datasets/panorama_scene.hpp"

namespace fluoro {

inline constexpr double kGoalRulerOffsetsMm[] = {-80.0, -50.0, -30.0, 30.0, 50.0, 80.0};
inline constexpr uint32_t kGoalSeeds[] = {11u, 12u, 13u};

// 512^2, 6-8 frames, 40-55 % overlap, landmarks 320-420 mm apart, k-wires and a clamp.
inline PanoramaSceneParams goal_set_params(double ruler_offset_mm, uint32_t seed) {
  PanoramaSceneParams params;
  params.ruler_offset_mm = ruler_offset_mm;
  params.seed = seed;
  params.frames = 6 + int(seed % 3);
  params.overlap = params.frames == 6 ? 0.4 : params.frames == 7 ? 0.5 : 0.55;
  params.landmark_distance_mm = 300 + 50 * (seed % 3) + 20;
  return params;
}

// The goal table through a distortion and a fitted dewarp map (--goals-dewarp); returns 0.
int run_dewarp_goals();

// The generator's sets beyond the goal table (seeds 31-45 at the six offsets), every frame's
// placement against the truth (--extra [OFFSET SEED]); returns 0.
int run_extra_sets(int argc, char** argv);

// The cv::Stitcher (SCANS) table of docs/panorama.md on the goal sets; returns 0.
int run_stitcher_comparison();

}  // namespace fluoro
