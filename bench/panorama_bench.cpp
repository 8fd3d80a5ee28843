// Long-bone panoramas: the whole `fluoro panorama` work (read 10 frames of 1024^2, align, compose,
// write the 16-bit PNG) as a Google Benchmark, and with --goals the accuracy table of
// docs/panorama.md (lengths without and with the realignment, seams, gaps) on generated sets, and
// with --stitcher OpenCV's cv::Stitcher (SCANS) on the same sets.
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "bench/panorama_goal_sets.hpp"
#include "bench/panorama_frames.hpp"
#include "datasets/panorama_scene.hpp"
#include "engine/image_io.hpp"
#include "engine/image_mat.hpp"
#include "pipelines/panorama/panorama.hpp"

namespace fluoro {
namespace {

PanoramaSceneParams bench_params() {
  PanoramaSceneParams p;
  p.pixels = 1024;
  p.frames = 10;
  p.overlap = 0.6;
  p.landmark_distance_mm = 450;
  p.seed = 2;
  return p;
}

// The frames on disk, as the command reads them.
const std::vector<std::string>& bench_files() {
  static std::vector<std::string> files = [] {
    const PanoramaScene s = make_panorama_scene(bench_params());
    const auto dir = std::filesystem::temp_directory_path() / "fluoro_panorama_bench";
    std::filesystem::create_directories(dir);
    std::vector<std::string> f;
    for (size_t i = 0; i < s.images.size(); ++i) {
      f.push_back((dir / ("f" + std::to_string(i) + ".png")).string());
      write_png_u16(s.images[i].pixels, s.images[i].width, s.images[i].height, f.back());
    }
    return f;
  }();
  return files;
}

void BM_PanoramaWholeCommand(benchmark::State& state) {
  const auto& files = bench_files();
  const std::string out = (std::filesystem::temp_directory_path() / "fluoro_panorama_bench" / "pano.png").string();
  for (auto _ : state) {
    std::vector<cv::Mat> frames;
    for (const auto& f : files) {
      const Image im = read_image(f);
      frames.push_back(mat_view(im).clone());
    }
    const Panorama p = align_panorama(frames, {}, std::nullopt);
    if (!p.failure.empty()) state.SkipWithError(p.failure.c_str());
    const cv::Mat pano = compose_panorama(frames, p, PanoramaBlend::Max);
    std::vector<uint16_t> px(size_t(pano.total()));
    for (int y = 0; y < pano.rows; ++y)
      for (int x = 0; x < pano.cols; ++x)
        px[size_t(y) * size_t(pano.cols) + size_t(x)] = uint16_t(std::clamp(std::lround(pano.at<float>(y, x)), 0L, 65535L));
    write_png_u16(px, pano.cols, pano.rows, out);
  }
}
BENCHMARK(BM_PanoramaWholeCommand)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_PanoramaAlign(benchmark::State& state) {
  PanoramaSceneParams params = bench_params();
  params.pixels = int(state.range(0));
  const auto frames = frames_of(make_panorama_scene(params));
  for (auto _ : state) benchmark::DoNotOptimize(align_panorama(frames, {}, std::nullopt));
}
BENCHMARK(BM_PanoramaAlign)->Arg(512)->Arg(1024)->Unit(benchmark::kMillisecond)->UseRealTime();

// --- goals ---

int landmark_frame(const PanoramaScene& s, int k) {
  const Eigen::Vector2d c = 0.5 * Eigen::Vector2d(s.images[0].width - 1, s.images[0].height - 1);
  int best = 0;
  for (int i = 1; i < int(s.images.size()); ++i)
    if ((project_in_frame(s, i, s.landmarks[k]) - c).norm() < (project_in_frame(s, best, s.landmarks[k]) - c).norm()) best = i;
  return best;
}

Eigen::Vector2d in_panorama(const Panorama& p, int frame, const Eigen::Vector2d& px) {
  return (p.frames[size_t(frame)].H_panorama_frame * Eigen::Vector3d(px.x(), px.y(), 1)).head<2>();
}

double length_error_percent(const PanoramaScene& s, const Panorama& p) {
  const int a = landmark_frame(s, 0), b = landmark_frame(s, 1);
  const double d = (in_panorama(p, b, project_in_frame(s, b, s.landmarks[1])) -
                    in_panorama(p, a, project_in_frame(s, a, s.landmarks[0]))).norm() * p.mm_per_pixel;
  return 100 * (d - s.true_length_mm) / s.true_length_mm;
}

// Largest distance between the panorama pixels of one bone-edge point seen in two consecutive frames.
double worst_seam_px(const PanoramaScene& s, const Panorama& p) {
  const Eigen::Vector2d c = 0.5 * Eigen::Vector2d(s.images[0].width - 1, s.images[0].height - 1);
  const double r = 0.4 * s.images[0].width;
  double worst = 0;
  for (int i = 0; i + 1 < int(s.images.size()); ++i)
    for (double x = -400; x <= 400; x += 2) {
      const Eigen::Vector3d edge(x, 15, s.bone_plane_mm);
      const Eigen::Vector2d a = project_in_frame(s, i, edge), b = project_in_frame(s, i + 1, edge);
      if ((a - c).norm() > r || (b - c).norm() > r) continue;
      worst = std::max(worst, (in_panorama(p, i, a) - in_panorama(p, i + 1, b)).norm());
    }
  return worst;
}

int run_goals() {
  std::printf("| ruler - bone plane (mm) | seed | frames | graduations hidden by the clamp | length (mm) | "
              "error without realignment | error with realignment | worst seam (px) | status |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|\n");
  double worst = 0;
  int failures = 0;
  for (const double offset : kGoalRulerOffsetsMm)
    for (const uint32_t seed : kGoalSeeds) {
      const PanoramaSceneParams params = goal_set_params(offset, seed);
      const PanoramaScene s = make_panorama_scene(params);
      const auto frames = frames_of(s);
      const Panorama ruler = align_panorama(frames, {}, std::nullopt);
      PlaneContours c;
      c.first = s.contour_first_frame;
      c.polylines[0] = s.contour[0];
      c.polylines[1] = s.contour[1];
      const Panorama bone = align_panorama(frames, {}, c);
      const bool ok = ruler.failure.empty() && bone.failure.empty() && bone.plane == "contours";
      if (!ok) {
        ++failures;
        std::printf("| %+.0f | %u | %d | %.0f %% | %.0f | - | - | - | failed: %s |\n", offset, seed, params.frames,
                    100 * s.clamp_hidden_fraction, s.true_length_mm, (ruler.failure + bone.failure).c_str());
        continue;
      }
      const double with = length_error_percent(s, bone);
      worst = std::max(worst, std::abs(with));
      std::printf("| %+.0f | %u | %d | %.0f %% | %.0f | %+.2f %% | %+.3f %% | %.2f | ok |\n", offset, seed, params.frames,
                  100 * s.clamp_hidden_fraction, s.true_length_mm, length_error_percent(s, ruler), with,
                  worst_seam_px(s, bone));
    }
  std::printf("\nworst length error with the realignment: %.3f %% (goal 0.5 %%); sets not composed: %d\n", worst, failures);
  int refused = 0, gaps = 0;
  for (const uint32_t seed : {21u, 22u, 23u, 24u, 25u})
    for (const int gap : {1, 3}) {
      PanoramaSceneParams params;
      params.seed = seed;
      params.gap_after_frame = gap;
      const Panorama p = align_panorama(frames_of(make_panorama_scene(params)), {}, std::nullopt);
      ++gaps;
      refused += !p.frames[size_t(gap + 1)].aligned;
    }
  std::printf("sets with a gap refused at the frame after it: %d of %d\n", refused, gaps);
  return 0;
}

}  // namespace
}  // namespace fluoro

int main(int argc, char** argv) {
  if (argc > 1 && std::strcmp(argv[1], "--goals") == 0) return fluoro::run_goals();
  if (argc > 1 && std::strcmp(argv[1], "--stitcher") == 0) return fluoro::run_stitcher_comparison();
  if (argc > 1 && std::strcmp(argv[1], "--goals-dewarp") == 0) return fluoro::run_dewarp_goals();
  if (argc > 1 && std::strcmp(argv[1], "--extra") == 0) return fluoro::run_extra_sets(argc, argv);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
