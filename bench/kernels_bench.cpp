// Every op x backend x size (Google Benchmark). Counters: samples/s for ray marching (trilinear
// samples actually taken), poses/s for the GPR score, voxels/s for the gradient field. Set-up
// (phantom, upload, gradient field; for vulkan also device creation and shader compilation) happens
// outside the timed loops and is timed on its own (BM_Upload, BM_VulkanSetup).
// Every op runs on cpu and vulkan side by side; a machine without a Vulkan device skips the
// vulkan rows with a message.
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <memory>
#include <numbers>
#include <random>

#include "datasets/c_arm.hpp"
#include "datasets/phantom.hpp"
#include "engine/attenuation.hpp"
#include "engine/backend.hpp"
#include "engine/ray_setup.hpp"
#include "engine/xray.hpp"
#include "kernels/backend_registry.hpp"
#include "pipelines/registration/edge_pixels.hpp"

#if FLUORO_HAVE_VULKAN
#include "kernels/vulkan/vulkan_backend.hpp"
#include "kernels/vulkan/vulkan_context.hpp"
#endif

namespace fluoro {
namespace {

const Volume& phantom_mu(int size) {
  static std::map<int, Volume> cache;
  auto it = cache.find(size);
  if (it == cache.end()) {
    PhantomParams p;
    p.kind = PhantomKind::pelvis;
    p.size = size;
    it = cache.emplace(size, hu_to_attenuation(make_phantom(p).hu)).first;
  }
  return it->second;
}

CArmGeometry detector(int pixels) {
  CArmGeometry g;
  g.pixels = pixels;
  g.pixel_mm = 0.6 * 512.0 / pixels;  // the same detector area at every resolution
  return g;
}

// Trilinear samples a DRR of this geometry takes (the same count on every backend).
// The backend, or null after marking the benchmark skipped (a vulkan backend without a device).
std::unique_ptr<Backend> backend_or_skip(benchmark::State& state, const char* name) {
  try {
    return make_backend(name);
  } catch (const BackendUnavailable& e) {
    state.SkipWithError(e.what());
    return nullptr;
  }
}

double drr_samples(const VolumeGeometry& g, const PinholeCamera& cam, const Pose& pose, double step) {
  const RaySetup s = make_ray_setup(g, pose, cam);
  double total = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) total += make_pixel_ray(s, x, y, step).n;
  return total;
}

void BM_GradientField(benchmark::State& state, const char* backend_name) {
  auto backend = backend_or_skip(state, backend_name);
  if (!backend) return;
  const Volume& mu = phantom_mu(int(state.range(0)));
  const auto dv = backend->upload(mu);
  for (auto _ : state) benchmark::DoNotOptimize(backend->gradient_field(*dv, {1.0, 0.0}));
  state.counters["voxels/s"] = benchmark::Counter(double(mu.geometry.voxel_count()), benchmark::Counter::kIsIterationInvariantRate);
}

void BM_Drr(benchmark::State& state, const char* backend_name) {
  auto backend = backend_or_skip(state, backend_name);
  if (!backend) return;
  const Volume& mu = phantom_mu(int(state.range(0)));
  const PinholeCamera cam = c_arm_view(detector(int(state.range(1))), 20, 5);
  const Pose pose = Pose::Identity();
  const auto dv = backend->upload(mu);
  const double step = mu.geometry.spacing.x();  // one sample per voxel
  for (auto _ : state) benchmark::DoNotOptimize(backend->drr(*dv, std::span(&pose, 1), std::span(&cam, 1), {step, {}}));
  state.counters["samples/s"] = benchmark::Counter(drr_samples(mu.geometry, cam, pose, step),
                                                   benchmark::Counter::kIsIterationInvariantRate);
}

void BM_Upload(benchmark::State& state, const char* backend_name) {
  auto backend = backend_or_skip(state, backend_name);
  if (!backend) return;
  const Volume& mu = phantom_mu(int(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(backend->upload(mu));
}

// The GPR score of a batch: poses x 3 views x edge pixels (the registration's inner loop).
// range(2) = 0: trilinear reads of the field on the CT grid (2 mm voxels), a sample every 1 mm;
// 1: the seed's nearest reads of the field resampled to 1 mm, every 1 mm; 2: trilinear reads, a
// sample every 2 mm (one per voxel).
// The GPR benchmarks' scene: three 512^2 C-arm views of the 128^3 phantom and, per view, the
// edge pixels registration sees (Canny edges of the phantom's DRR at the identity, an evenly
// spread subset of max_pixels in the detector's raster order).
struct GprBenchViews {
  std::vector<PinholeCamera> views;
  std::vector<EdgePixels> edges;
};
GprBenchViews gpr_bench_views(Backend& backend, const Volume& mu, int max_pixels) {
  GprBenchViews out;
  out.views = {c_arm_view(detector(512), 0), c_arm_view(detector(512), 60), c_arm_view(detector(512), 90, 10)};
  const Pose identity = Pose::Identity();
  const auto drrs = backend.drr(*backend.upload(mu), std::span(&identity, 1), out.views, {1.0, {}});
  EdgeDetectionParams ep;
  ep.max_pixels = max_pixels;
  for (const Image& d : drrs)
    out.edges.push_back(
        detect_edge_pixels(drr_to_xray(d, display_mapping(d, 1000.0)), XrayPolarity::log_domain, ep, "drr"));
  return out;
}

void BM_GprScore(benchmark::State& state, const char* backend_name) {
  auto backend = backend_or_skip(state, backend_name);
  if (!backend) return;
  const int n_poses = int(state.range(0)), n_pixels = int(state.range(1));
  const bool nearest = state.range(2) == 1;
  const Volume& mu = phantom_mu(128);
  const auto grad = backend->gradient_field(*backend->upload(mu), {1.0, nearest ? 1.0 : 0.0});
  GprParams params;
  params.projection.sampling = nearest ? Sampling::nearest : Sampling::trilinear;
  params.projection.step_mm = state.range(2) == 2 ? 2.0 : 1.0;
  const auto [views, edges] = gpr_bench_views(*backend, mu, n_pixels);
  std::mt19937 rng(7);
  std::vector<Pose> poses;
  std::normal_distribution<double> small(0, 0.05), shift(0, 5);
  for (int p = 0; p < n_poses; ++p) {
    const Eigen::Vector3d translation{shift(rng), shift(rng), shift(rng)};  // drawn first, as GCC did
    const Eigen::Vector3d rotation{small(rng), small(rng), small(rng)};
    poses.push_back(pose_from_rotation_vector(rotation, translation));
  }
  for (auto _ : state) benchmark::DoNotOptimize(backend->gpr_score(*grad, poses, views, edges, params));
  state.counters["poses/s"] = benchmark::Counter(double(n_poses), benchmark::Counter::kIsIterationInvariantRate);
  double rays = 0;
  for (const auto& e : edges) rays += double(e.pixels.size()) * n_poses;
  state.counters["rays/s"] = benchmark::Counter(rays, benchmark::Counter::kIsIterationInvariantRate);
}

// What a batch saves the fine stages' optimisers: the 13 poses of a finite-difference stencil
// (the centre and +-0.25 degrees / mm on each of the six parameters, as quasi_newton.hpp scores
// them) in one gpr_score call (range(1) == 1) or in 13 calls of one pose (0, as the simplex's
// steps go); 4,000 edge pixels per view, like the last fine stage. Per-pose cost: the time / 13.
void BM_GprScoreStencil(benchmark::State& state, const char* backend_name) {
  auto backend = backend_or_skip(state, backend_name);
  if (!backend) return;
  const bool batched = state.range(1) == 1;
  const Volume& mu = phantom_mu(128);
  const auto grad = backend->gradient_field(*backend->upload(mu), {0.5, 1.0});
  GprParams params;
  const auto [views, edges] = gpr_bench_views(*backend, mu, int(state.range(0)));
  const Pose identity = Pose::Identity();
  std::vector<Pose> poses{identity};
  for (int i = 0; i < 6; ++i)
    for (const double sign : {1.0, -1.0}) {
      Eigen::Vector3d r = Eigen::Vector3d::Zero(), t = Eigen::Vector3d::Zero();
      (i < 3 ? r[i] : t[i - 3]) = sign * (i < 3 ? 0.25 * std::numbers::pi / 180 : 0.25);
      poses.push_back(pose_from_rotation_vector(r, t));
    }
  for (auto _ : state) {
    if (batched) benchmark::DoNotOptimize(backend->gpr_score(*grad, poses, views, edges, params));
    else
      for (const Pose& p : poses) benchmark::DoNotOptimize(backend->gpr_score(*grad, std::span(&p, 1), views, edges, params));
  }
  state.counters["poses/s"] = benchmark::Counter(double(poses.size()), benchmark::Counter::kIsIterationInvariantRate);
}

// BM_GprScore's 64-pose batch (trilinear, 1 mm steps) on the field floored at range(0) per
// mille of its strongest voxel (Op::gradient_floor), and the relative change of the batch's
// summed score that the floor makes (score_change).
void BM_GprScoreFloored(benchmark::State& state, const char* backend_name) {
  auto backend = backend_or_skip(state, backend_name);
  if (!backend) return;
  const Volume& mu = phantom_mu(128);
  const auto field = backend->gradient_field(*backend->upload(mu), {1.0, 0.0});
  const auto floored = backend->floor_gradient(*field, {double(state.range(0)) / 1000.0});
  GprParams params;
  const auto [views, edges] = gpr_bench_views(*backend, mu, 5000);
  std::mt19937 rng(7);
  std::vector<Pose> poses;
  std::normal_distribution<double> small(0, 0.05), shift(0, 5);
  for (int p = 0; p < 64; ++p) {  // BM_GprScore's poses
    const Eigen::Vector3d translation{shift(rng), shift(rng), shift(rng)};
    const Eigen::Vector3d rotation{small(rng), small(rng), small(rng)};
    poses.push_back(pose_from_rotation_vector(rotation, translation));
  }
  for (auto _ : state) benchmark::DoNotOptimize(backend->gpr_score(*floored, poses, views, edges, params));
  const auto before = backend->gpr_score(*field, poses, views, edges, params);
  const auto after = backend->gpr_score(*floored, poses, views, edges, params);
  double change = 0, total = 0;
  for (size_t p = 0; p < before.size(); ++p) {
    change += std::abs(after[p] - before[p]);
    total += before[p];
  }
  state.counters["score_change"] = change / total;
  state.counters["poses/s"] = benchmark::Counter(64.0, benchmark::Counter::kIsIterationInvariantRate);
}

// Dense gradient projection (the expected-edge map's input): every pixel of one 256^2 view.
void BM_GradientProjection(benchmark::State& state, const char* backend_name) {
  auto backend = backend_or_skip(state, backend_name);
  if (!backend) return;
  const Volume& mu = phantom_mu(128);
  const auto grad = backend->gradient_field(*backend->upload(mu), {1.0, 0.0});
  const int side = int(state.range(0));
  const PinholeCamera cam = c_arm_view(detector(side), 30);
  std::vector<std::vector<Eigen::Vector2f>> pixels(1);
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) pixels[0].emplace_back(float(x), float(y));
  const Pose pose = Pose::Identity();
  const ProjectionParams params{1.0, Sampling::trilinear};
  for (auto _ : state)
    benchmark::DoNotOptimize(backend->gradient_projection(*grad, std::span(&pose, 1), std::span(&cam, 1), pixels, params));
  state.counters["rays/s"] = benchmark::Counter(double(side) * side, benchmark::Counter::kIsIterationInvariantRate);
}

#if FLUORO_HAVE_VULKAN
// Vulkan set-up, apart from per-call times, each from a fresh device context: range(0) = 0:
// instance + device creation; 1: the same plus creating every shader's pipeline; 2: a cold start
// of the ops, i.e. a fresh backend running each op once on a 16^3 volume (lavapipe compiles a
// shader to machine code at its first dispatch, not at pipeline creation).
void BM_VulkanSetup(benchmark::State& state) {
  try {
    vulkan::Context probe(0);
  } catch (const BackendUnavailable& e) {
    state.SkipWithError(e.what());
    return;
  }
  PhantomParams pp;
  pp.kind = PhantomKind::femur;
  pp.size = 16;
  const Volume mu = hu_to_attenuation(make_phantom(pp).hu);
  const PinholeCamera cam = c_arm_view(detector(32), 0);
  const Pose pose = Pose::Identity();
  EdgePixels edges;
  edges.pixels = {Eigen::Vector2f(16, 16)};
  edges.directions = {Eigen::Vector2f(1, 0)};
  for (auto _ : state) {
    if (state.range(0) == 2) {
      auto b = vulkan::make_vulkan_backend(0, std::nullopt, false);
      const auto dv = b->upload(mu);
      const auto g = b->gradient_field(*dv, {1.0, 0.0});
      benchmark::DoNotOptimize(b->drr(*dv, std::span(&pose, 1), std::span(&cam, 1), {1.0, {}}));
      benchmark::DoNotOptimize(b->gpr_score(*g, std::span(&pose, 1), std::span(&cam, 1), std::span(&edges, 1), {}));
      continue;
    }
    vulkan::Context ctx(0);
    if (state.range(0) == 1)
      for (int s = 0; s <= int(vulkan::Shader::brick_occupancy); ++s) benchmark::DoNotOptimize(&ctx.pipeline(vulkan::Shader(s)));
  }
}
BENCHMARK(BM_VulkanSetup)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
#endif

BENCHMARK_CAPTURE(BM_Upload, cpu, "cpu")->Arg(256)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_GradientField, cpu, "cpu")->Arg(128)->Arg(256)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_GradientField, reference, "reference")->Arg(128)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Drr, cpu, "cpu")->Args({256, 256})->Args({256, 512})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Drr, reference, "reference")->Args({256, 256})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_GprScore, cpu, "cpu")->Args({1, 100, 0})->Args({1, 5000, 0})->Args({64, 5000, 0})->Args({64, 5000, 1})->Args({64, 5000, 2})->Unit(benchmark::kMillisecond)->UseRealTime();
// Process CPU time (both cores): comparable on a loaded machine, unlike wall time.
BENCHMARK_CAPTURE(BM_GprScoreStencil, cpu, "cpu")->Args({4000, 0})->Args({4000, 1})->Args({500, 0})->Args({500, 1})
    ->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK_CAPTURE(BM_GprScoreFloored, cpu, "cpu")->Arg(0)->Arg(10)->Arg(20)->Arg(50)->Arg(100)
    ->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK_CAPTURE(BM_GradientProjection, cpu, "cpu")->Arg(256)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Upload, vulkan, "vulkan")->Arg(256)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_GradientField, vulkan, "vulkan")->Arg(128)->Arg(256)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Drr, vulkan, "vulkan")->Args({256, 256})->Args({256, 512})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_GprScore, vulkan, "vulkan")->Args({1, 100, 0})->Args({1, 5000, 0})->Args({64, 5000, 0})->Args({64, 5000, 1})->Args({64, 5000, 2})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_GradientProjection, vulkan, "vulkan")->Arg(256)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_GprScore, reference, "reference")->Args({1, 5000, 0})->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace fluoro

BENCHMARK_MAIN();
