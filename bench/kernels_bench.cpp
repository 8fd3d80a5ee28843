// Every op x backend x size (Google Benchmark). Counters: samples/s for ray marching (trilinear
// samples actually taken), poses/s for the GPR score, voxels/s for the gradient field. Set-up
// (phantom, upload, gradient field; for vulkan also device creation and shader compilation) happens
// outside the timed loops and is timed on its own (BM_Upload, BM_VulkanSetup).
// Every op runs on cpu and vulkan side by side; a machine without a Vulkan device skips the
// vulkan rows with a message.
#include <benchmark/benchmark.h>
#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
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
#include "kernels/mesh/closest_point.hpp"
#include "pipelines/registration/bone_mesh.hpp"
#include "pipelines/registration/prepared_ct.hpp"
#include "pipelines/registration/registration.hpp"
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

// Issue 13, item 2: "sampling only where the gradient is", the Embree variant: intersect each ray
// with the bone's iso-surface mesh (every crossing) and sample only within +-3 sigma of each. Two
// halves of its cost, on a registration's own preparation of the 128^3 pelvis phantom (prepare_ct
// with the default options: the bone mesh and each fine stage's bone-only gradient field; range(0)
// is the stage) and BM_GprScore's 64 poses x 3 views x 5,000 edge pixels:
// - BM_SurfaceCrossings: every crossing of every ray through Embree (rtcOccluded1, or with
//   range(1) 1 rtcOccluded16 on 16 consecutive rays, with a filter that records each hit and lets
//   the ray go on), in parallel. Counters: crossings per ray,
//   samples per ray (at the stage's step) in the merged +-3 sigma intervals and over the whole
//   chord through the volume.
// - BM_GprScoreNearSurface: the cpu marcher on the stage's field (range(1) 0) or on that field
//   with every voxel farther than 3 sigma + half a voxel diagonal from the mesh zeroed (1): its
//   empty-space skipping then marches only bricks near the surface, about what intervals would
//   sample (in bricks of 4^3 voxels on this 2 mm phantom). score_change: the relative change of the batch's summed score
//   that dropping the rest makes.
constexpr double kBandSigmas = 3.0;

struct PhantomPreparation {
  std::unique_ptr<Backend> backend = make_backend("cpu");
  RegistrationOptions options;
  PreparedCt prepared;
};

const PhantomPreparation& phantom_preparation() {
  static const PhantomPreparation* p = [] {
    auto* out = new PhantomPreparation;
    PhantomParams phantom;
    phantom.kind = PhantomKind::pelvis;
    phantom.size = 128;
    out->prepared = prepare_ct(*out->backend, make_phantom(phantom).hu, out->options, nullptr);
    return out;
  }();
  return *p;
}

std::vector<Pose> gpr_bench_poses() {  // BM_GprScore's 64 poses
  std::mt19937 rng(7);
  std::vector<Pose> poses;
  std::normal_distribution<double> small(0, 0.05), shift(0, 5);
  for (int p = 0; p < 64; ++p) {
    const Eigen::Vector3d translation{shift(rng), shift(rng), shift(rng)};
    const Eigen::Vector3d rotation{small(rng), small(rng), small(rng)};
    poses.push_back(pose_from_rotation_vector(rotation, translation));
  }
  return poses;
}

// The crossings of up to 16 rays (one, or a packet's lanes).
struct CrossingQuery {
  RTCIntersectContext context;  // first: Embree hands the filter a pointer to it
  float hits[16][32];
  int count[16] = {};
};

void record_crossing(const RTCFilterFunctionNArguments* args) {
  auto* q = reinterpret_cast<CrossingQuery*>(args->context);
  for (unsigned lane = 0; lane < args->N; ++lane) {
    if (args->valid[lane] == 0) continue;
    // A single ray's hit comes as lane 0 of N = 1; a packet's as its own lanes.
    const unsigned ray = args->N == 1 ? 0 : lane;
    if (q->count[ray] < 32) q->hits[ray][q->count[ray]++] = RTCRayN_tfar(args->ray, args->N, lane);
    args->valid[lane] = 0;  // not an occluder: the traversal goes on to every crossing
  }
}

void BM_SurfaceCrossings(benchmark::State& state) {
  const PhantomPreparation& prep = phantom_preparation();
  const GprStage& stage = prep.options.stages[size_t(state.range(0))];
  const BoneMesh& mesh = prep.prepared.mesh;
  const Volume& mu = phantom_mu(128);
  const auto [views, edges] = gpr_bench_views(*prep.backend, mu, 5000);
  const std::vector<Pose> poses = gpr_bench_poses();

  RTCDevice device = rtcNewDevice(nullptr);
  RTCScene scene = rtcNewScene(device);
  rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
  RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                        3 * sizeof(float), mesh.vertices.size()));
  for (size_t i = 0; i < mesh.vertices.size(); ++i)
    for (int a = 0; a < 3; ++a) v[3 * i + size_t(a)] = float(mesh.vertices[i][a]);
  auto* t = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                           3 * sizeof(unsigned), mesh.triangles.size()));
  for (size_t i = 0; i < mesh.triangles.size(); ++i)
    for (int a = 0; a < 3; ++a) t[3 * i + size_t(a)] = unsigned(mesh.triangles[i][size_t(a)]);
  rtcSetGeometryOccludedFilterFunction(geometry, record_crossing);
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(scene, geometry);
  rtcReleaseGeometry(geometry);
  rtcCommitScene(scene);

  // Each ray in the CT's physical frame: from the source, a unit direction, t in mm (the
  // marchers' own parameter), and its chord through the volume's box.
  struct Ray {
    Eigen::Vector3f origin, dir;
    float t0, t1;
  };
  std::vector<Ray> rays;
  for (const Pose& pose : poses)
    for (size_t view = 0; view < views.size(); ++view) {
      const RaySetup setup = make_ray_setup(mu.geometry, pose, views[view]);
      const Pose T_ct_world = pose.inverse();
      const Eigen::Vector3d source = T_ct_world * views[view].source();
      const Eigen::Matrix3d cam_to_ct = T_ct_world.rotation() * views[view].R.transpose();
      // In 8 x 8 tile order, as the marchers take them: neighbours follow one another.
      for (const uint32_t at : tile_order(edges[view].pixels)) {
        const Eigen::Vector2f& px = edges[view].pixels[at];
        const PixelRay r = make_pixel_ray(setup, px.x(), px.y(), stage.step_mm);
        const Eigen::Vector3d d = (cam_to_ct * setup.kinv * Eigen::Vector3d(px.x(), px.y(), 1)).normalized();
        rays.push_back({source.cast<float>(), d.cast<float>(), float(r.t0), float(r.t0 + r.n * r.h)});
      }
    }
  const float half = float(kBandSigmas * stage.sigma_mm);
  std::vector<int> crossings(rays.size());
  std::vector<float> band_mm(rays.size());
  // The merged +-3 sigma intervals around a ray's crossings, within its chord.
  auto band = [&](const Ray& r, float* hits, int count) {
    std::sort(hits, hits + count);
    float length = 0, end = r.t0;
    for (int k = 0; k < count; ++k) {
      const float a = std::max(end, hits[k] - half), b = std::min(r.t1, hits[k] + half);
      if (b > a) length += b - a;
      end = std::max(end, b);
    }
    return length;
  };
  const bool packets = state.range(1) == 1;  // 16 consecutive (tile-ordered, so coherent) rays at once
  for (auto _ : state) {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size() / 16, 16), [&](const tbb::blocked_range<size_t>& range) {
      for (size_t b = range.begin(); b != range.end(); ++b) {
        CrossingQuery q;
        rtcInitIntersectContext(&q.context);
        if (packets) {
          RTCRay16 ray{};
          int valid[16];
          for (int l = 0; l < 16; ++l) {
            const Ray& r = rays[16 * b + size_t(l)];
            valid[l] = -1;
            ray.org_x[l] = r.origin.x(), ray.org_y[l] = r.origin.y(), ray.org_z[l] = r.origin.z();
            ray.dir_x[l] = r.dir.x(), ray.dir_y[l] = r.dir.y(), ray.dir_z[l] = r.dir.z();
            ray.tnear[l] = r.t0;
            ray.tfar[l] = r.t1;
            ray.mask[l] = ~0u;
          }
          rtcOccluded16(valid, scene, &q.context, &ray);
          for (int l = 0; l < 16; ++l) {
            const size_t i = 16 * b + size_t(l);
            crossings[i] = q.count[l];
            band_mm[i] = band(rays[i], q.hits[l], q.count[l]);
          }
        } else {
          for (int l = 0; l < 16; ++l) {
            const size_t i = 16 * b + size_t(l);
            const Ray& r = rays[i];
            q.count[0] = 0;
            RTCRay ray{};
            ray.org_x = r.origin.x(), ray.org_y = r.origin.y(), ray.org_z = r.origin.z();
            ray.dir_x = r.dir.x(), ray.dir_y = r.dir.y(), ray.dir_z = r.dir.z();
            ray.tnear = r.t0;
            ray.tfar = r.t1;
            ray.mask = ~0u;
            rtcOccluded1(scene, &q.context, &ray);
            crossings[i] = q.count[0];
            band_mm[i] = band(r, q.hits[0], q.count[0]);
          }
        }
      }
    });
    benchmark::DoNotOptimize(band_mm.data());
  }
  double hits = 0, banded = 0, chord = 0;
  const size_t counted = rays.size() / 16 * 16;
  for (size_t i = 0; i < counted; ++i) {
    hits += crossings[i];
    banded += band_mm[i];
    chord += std::max(0.0f, rays[i].t1 - rays[i].t0);
  }
  const double n = double(counted);
  state.counters["triangles"] = double(mesh.triangles.size());
  state.counters["crossings/ray"] = hits / n;
  state.counters["band_samples/ray"] = banded / n / stage.step_mm;
  state.counters["chord_samples/ray"] = chord / n / stage.step_mm;
  state.counters["rays/s"] = benchmark::Counter(n, benchmark::Counter::kIsIterationInvariantRate);
  rtcReleaseScene(scene);
  rtcReleaseDevice(device);
}

void BM_GprScoreNearSurface(benchmark::State& state) {
  const PhantomPreparation& prep = phantom_preparation();
  Backend& backend = *prep.backend;
  const size_t stage_index = size_t(state.range(0));
  const GprStage& stage = prep.options.stages[stage_index];
  const auto& field = prep.prepared.gradients[stage_index];
  VectorField banded = backend.download_gradient(*field);
  const VolumeGeometry& g = banded.geometry;
  const MeshClosestPoint surface(TriangleMesh{prep.prepared.mesh.vertices, prep.prepared.mesh.triangles}, "mesh");
  const double band = kBandSigmas * stage.sigma_mm + 0.5 * g.spacing.norm();
  std::vector<Eigen::Vector3d> points;
  std::vector<size_t> index;
  for (int k = 0; k < g.size.z(); ++k)
    for (int j = 0; j < g.size.y(); ++j)
      for (int i = 0; i < g.size.x(); ++i) {
        const size_t at = g.linear_index(i, j, k);
        const auto& w = banded.vectors[at];
        if (w[0] == 0 && w[1] == 0 && w[2] == 0) continue;
        points.push_back(g.index_to_physical(Eigen::Vector3d(i, j, k)));
        index.push_back(at);
      }
  const std::vector<SurfacePoint> nearest = surface.closest(points);
  size_t kept = 0;
  for (size_t n = 0; n < index.size(); ++n) {
    if (nearest[n].distance > band) banded.vectors[index[n]] = {0, 0, 0};
    else ++kept;
  }
  const auto near_surface = backend.upload(banded);
  const auto& marched = state.range(1) == 1 ? near_surface : field;
  const auto [views, edges] = gpr_bench_views(backend, phantom_mu(128), 5000);
  const std::vector<Pose> poses = gpr_bench_poses();
  GprParams params;
  params.projection.step_mm = stage.step_mm;
  for (auto _ : state) benchmark::DoNotOptimize(backend.gpr_score(*marched, poses, views, edges, params));
  const auto before = backend.gpr_score(*field, poses, views, edges, params);
  const auto after = backend.gpr_score(*near_surface, poses, views, edges, params);
  double change = 0, total = 0;
  for (size_t p = 0; p < before.size(); ++p) {
    change += std::abs(after[p] - before[p]);
    total += before[p];
  }
  state.counters["score_change"] = change / total;
  state.counters["kept_of_nonzero_voxels"] = double(kept) / double(std::max<size_t>(1, index.size()));
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
BENCHMARK(BM_SurfaceCrossings)->ArgsProduct({{0, 1, 2}, {0, 1}})->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK(BM_GprScoreNearSurface)->ArgsProduct({{0, 1, 2}, {0, 1}})->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime()->UseRealTime();
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
