// The calibration pipeline's speed, with its accuracy as counters.
// Distortion correction at 1024^2: `dewarp fit` (hole detection, lattice, both map models) on a
// clean grid and on a noisy one with 35 % of the holes hidden and dust, its accuracy between the
// holes over four C-arm orientations (counters, plate mm), and `dewarp apply` of a 16-bit image
// once the map is loaded (the goal: at most 10 ms), plus the one-off remap tables, and a
// robustness sweep over many noisy scenes with 40 % of the holes hidden.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <map>
#include <opencv2/core.hpp>

#include "datasets/dewarp_grid.hpp"
#include "pipelines/calibration/dewarp_fit.hpp"

namespace fluoro {
namespace {

// condition 0: clean (blur only); 1: noise 5 % of the hole contrast, 35 % hidden, 40 dust specks.
const DewarpScene& dewarp_scene(int condition, int orientation) {
  static std::map<std::pair<int, int>, DewarpScene> cache;
  const auto key = std::make_pair(condition, orientation);
  auto it = cache.find(key);
  if (it != cache.end()) return it->second;
  DewarpSceneOptions o;  // 1024^2, 0.38 mm pixels, 12 px of distortion at the FOV's edge
  o.seed = uint64_t(10 + orientation);
  o.orbit_deg = 90.0 * orientation;
  if (condition == 1) o.noise_sigma = 0.05, o.hidden_fraction = 0.35, o.dust_count = 40;
  return cache.emplace(key, make_dewarp_scene(o)).first->second;
}

// Args: model (0 polynomial, 1 bilinear), condition. Timed: the fit of orientation 0. Counters: the
// error between holes (mean of the four orientations' means, largest max) and elsewhere in the FOV.
void BM_DewarpFit(benchmark::State& state) {
  DewarpFitOptions options;
  options.model = state.range(0) == 0 ? DewarpModel::polynomial : DewarpModel::bilinear;
  const int condition = int(state.range(1));
  const DewarpScene& s = dewarp_scene(condition, 0);
  int used = 0;
  for (auto _ : state) {
    const DewarpFit fit = fit_dewarp(s.image, s.grid, options);
    used = fit.holes_used;
    benchmark::DoNotOptimize(fit.ok);
  }
  double mean = 0, max = 0, else_mean = 0, else_max = 0, hidden = 0;
  for (int orientation = 0; orientation < 4; ++orientation) {
    const DewarpScene& sc = dewarp_scene(condition, orientation);
    const DewarpFit fit = fit_dewarp(sc.image, sc.grid, options);
    if (!fit.ok) {
      state.SkipWithError(("fit failed: " + fit.reason).c_str());
      return;
    }
    const DewarpMapError e = dewarp_map_error(sc, [&](const Eigen::Vector2d& d) { return fit.map->correct_point(d); });
    mean += e.between.mean_mm / 4, max = std::max(max, e.between.max_mm);
    else_mean += e.elsewhere.mean_mm / 4, else_max = std::max(else_max, e.elsewhere.max_mm);
    hidden += sc.hidden_fraction / 4;
  }
  state.counters["holes_used"] = used;
  state.counters["hidden"] = hidden;
  state.counters["between_mean_mm"] = mean;
  state.counters["between_max_mm"] = max;
  state.counters["elsewhere_mean_mm"] = else_mean;
  state.counters["elsewhere_max_mm"] = else_max;
}
BENCHMARK(BM_DewarpFit)->Args({0, 0})->Args({1, 0})->Args({0, 1})->Args({1, 1})->Unit(benchmark::kMillisecond);

// Robustness: `count` noisy scenes with 40 % of the holes hidden and 40 dust specks, orientations
// 37 deg apart, edge displacement 10, 12.5 and 15 px (at 1024^2). Args: size, count. Timed: nothing
// useful (one pass renders and fits them all). Counters: failed fits, scenes whose between-holes mean
// exceeds the 0.05 mm goal (a mis-indexed patch shows as millimetres), the worst mean and max.
void BM_DewarpRobustness(benchmark::State& state) {
  const int size = int(state.range(0)), count = int(state.range(1));
  int failed = 0, off = 0;
  double worst_mean = 0, worst_max = 0;
  for (auto _ : state) {
    failed = off = 0;
    worst_mean = worst_max = 0;
    for (int k = 0; k < count; ++k) {
      DewarpSceneOptions o;
      o.size = size;
      o.pixel_mm = 0.38 * size / 1024.0;  // the same 0.38 mm pixels at every size
      o.seed = uint64_t(100 + k);
      o.orbit_deg = 37.0 * k;
      o.noise_sigma = 0.05, o.hidden_fraction = 0.4, o.dust_count = 40;
      o.edge_displacement_px = 10 + (k % 3) * 2.5;
      const DewarpScene s = make_dewarp_scene(o);
      const DewarpFit fit = fit_dewarp(s.image, s.grid);
      if (!fit.ok) {
        ++failed;
        continue;
      }
      const DewarpMapError e = dewarp_map_error(s, [&](const Eigen::Vector2d& d) { return fit.map->correct_point(d); });
      off += e.between.mean_mm > 0.05;
      worst_mean = std::max(worst_mean, e.between.mean_mm), worst_max = std::max(worst_max, e.between.max_mm);
    }
  }
  state.counters["scenes"] = count;
  state.counters["failed"] = failed;
  state.counters["off_goal"] = off;
  state.counters["worst_mean_mm"] = worst_mean;
  state.counters["worst_max_mm"] = worst_max;
}
BENCHMARK(BM_DewarpRobustness)->Args({512, 24})->Args({1024, 8})->Iterations(1)->Unit(benchmark::kSecond);

const DewarpMap& dewarp_map() {
  static const DewarpMap map = *fit_dewarp(dewarp_scene(0, 0).image, dewarp_scene(0, 0).grid).map;
  return map;
}

// `dewarp apply` on a 16-bit 1024^2 image with the map loaded and its remap tables built. Arg:
// OpenCV threads (0: its default, every core; 1: one core, the time a busy machine still gives).
void BM_DewarpApply(benchmark::State& state) {
  const int threads_before = cv::getNumThreads();
  if (state.range(0) > 0) cv::setNumThreads(int(state.range(0)));
  const DewarpScene& s = dewarp_scene(0, 0);
  cv::Mat image(s.image.height, s.image.width, CV_16U);
  for (int v = 0; v < image.rows; ++v)
    for (int u = 0; u < image.cols; ++u) image.at<uint16_t>(v, u) = uint16_t(s.image.at(u, v));
  const DewarpMap& map = dewarp_map();
  benchmark::DoNotOptimize(map.correct_image(image));  // builds the tables
  for (auto _ : state) benchmark::DoNotOptimize(map.correct_image(image));
  cv::setNumThreads(threads_before);
}
BENCHMARK(BM_DewarpApply)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// The one-off cost after loading a map: its remap tables (a fresh map each time).
void BM_DewarpRemapTables(benchmark::State& state) {
  const nlohmann::json j = dewarp_map().to_json();
  const cv::Mat image(1024, 1024, CV_16U, cv::Scalar(1000));
  for (auto _ : state) {
    const DewarpMap map = DewarpMap::from_json(j, "bench");
    benchmark::DoNotOptimize(map.correct_image(image));
  }
}
BENCHMARK(BM_DewarpRemapTables)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace fluoro

BENCHMARK_MAIN();
