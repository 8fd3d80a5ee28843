// One suite for every op on every backend, each against the reference backend (ggml's
// test-backend-ops idea): tolerances per op, NaN checks, and output extents that must match.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <thread>

#include "datasets/c_arm.hpp"
#include "datasets/phantom.hpp"
#include "engine/attenuation.hpp"
#include "engine/backend.hpp"
#include "engine/error.hpp"
#include "engine/volume_io.hpp"
#include "kernels/backend_registry.hpp"
#include "tests/test_scenes.hpp"

namespace fluoro {
namespace {

struct Scene {
  std::string name;
  Volume mu;
  std::vector<PinholeCamera> views;
  std::vector<Pose> poses;
};

// Sizes that are not multiples of any SIMD width or packet size, a non-identity direction, and
// anisotropic spacing.
Scene phantom_scene() {
  PhantomParams p;
  p.kind = PhantomKind::femur;
  p.size = 45;
  Scene s{"femur45", hu_to_attenuation(make_phantom(p).hu), {}, {}};
  CArmGeometry g;
  g.pixels = 53;
  g.pixel_mm = 5.0;
  s.views = {c_arm_view(g, 0), c_arm_view(g, 75, 10)};
  s.poses = {Pose::Identity(), pose_from_rotation_vector(Eigen::Vector3d(0.05, -0.1, 0.2), Eigen::Vector3d(3, -4, 5)),
             pose_from_rotation_vector(Eigen::Vector3d(-0.2, 0.1, 0.0), Eigen::Vector3d(-6, 2, 1))};
  return s;
}

Scene oblique_scene() {
  const Eigen::Matrix3d D = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -1, 2).normalized()).toRotationMatrix();
  Scene s{"oblique", test::make_volume({23, 31, 17}, {1.7, 1.1, 2.3}, [](const Eigen::Vector3d& x) {
            return float(0.02 * (x.norm() < 14) + 0.01 * std::exp(-(x - Eigen::Vector3d(4, 5, -3)).squaredNorm() / 60.0));
          }, D), {}, {}};
  s.views = {test::camera_looking_at_origin(250, 300, 37, 29, Eigen::Vector3d(0.3, 0.2, 1)),
             test::camera_looking_at_origin(250, 300, 19, 41, Eigen::Vector3d(1, 0.1, 0.2))};
  s.poses = {Pose::Identity(), pose_from_rotation_vector(Eigen::Vector3d(0.3, 0.1, -0.2), Eigen::Vector3d(1, 2, 3))};
  return s;
}

// A small blob off the centre of a larger oblique, anisotropic volume: its occupied bricks' box is
// a small part of the volume and its projection a small part of each image, so that the cpu
// backend's culling of rays that miss it (and its marching only inside it) is exercised, up to
// the projection's edges and through an image window.
Scene blob_scene() {
  const Eigen::Matrix3d D = Eigen::AngleAxisd(-0.4, Eigen::Vector3d(2, 1, -1).normalized()).toRotationMatrix();
  Scene s{"blob", test::make_volume({43, 37, 29}, {1.3, 1.1, 1.7}, [](const Eigen::Vector3d& x) {
            const double r = (x - Eigen::Vector3d(-12, 8, 5)).norm();
            return float(r < 6.5 ? 0.03 - 0.002 * r : 0.0);
          }, D), {}, {}};
  s.views = {test::camera_looking_at_origin(250, 300, 47, 39, Eigen::Vector3d(0.3, 0.2, 1)),
             test::camera_looking_at_origin(180, 400, 41, 43, Eigen::Vector3d(1, -0.4, 0.2))};
  s.poses = {Pose::Identity(), pose_from_rotation_vector(Eigen::Vector3d(-0.2, 0.3, 0.1), Eigen::Vector3d(4, -2, 3))};
  return s;
}

const Scene& scene(int i) {
  static const Scene scenes[] = {phantom_scene(), oblique_scene(), blob_scene()};
  return scenes[i];
}

std::vector<EdgePixels> edge_pixels_for(const Scene& s) {
  // A deterministic spread of pixels (sub-pixel positions) with assorted directions.
  std::vector<EdgePixels> e(s.views.size());
  for (size_t v = 0; v < s.views.size(); ++v)
    for (int i = 0; i < 157; ++i) {
      const float u = float((i * 37) % s.views[v].width) + 0.25f, w = float((i * 53) % s.views[v].height) + 0.5f;
      const float a = float(i) * 0.7f;
      e[v].pixels.emplace_back(u, w);
      e[v].directions.emplace_back(std::cos(a), std::sin(a));
    }
  return e;
}

class BackendTest : public ::testing::TestWithParam<std::tuple<std::string, int>> {
 protected:
  void SetUp() override {
    try {
      backend_ = make_backend(std::get<0>(GetParam()));
    } catch (const BackendUnavailable& e) {  // built in, but no device here (say, no Vulkan driver)
      GTEST_SKIP() << e.what();
    }
    reference_ = make_backend("reference");
  }
  const Scene& scene_() const { return scene(std::get<1>(GetParam())); }
  // An op a backend does not support is skipped, not failed (ggml's supports_op).
  bool skip_unless(Op op) const { return !backend_->supports(op); }
  std::unique_ptr<Backend> backend_, reference_;
};

// Every backend but the oracle against the reference backend.
class BackendEquivalence : public BackendTest {};
// What every backend, the oracle included, must do on its own: validation, empty batches,
// concurrent calls (engine/backend.hpp's contract).
class BackendContract : public BackendTest {};

TEST_P(BackendEquivalence, GradientField) {
  if (skip_unless(Op::gradient_field)) GTEST_SKIP() << "gradient_field not supported";
  // On the volume's grid, and resampled to a finer one that is no multiple of it (1.3 mm before:
  // 7.6 million voxels for the femur's 5.7 mm grid, 27 s of the reference under ASan).
  // Then between the smallest and largest spacing, keeping the coarser axes (the oblique scene's
  // 1.7 x 1.1 x 2.3 mm: x and y resampled, z kept).
  const Eigen::Vector3d& spacing = scene_().mu.geometry.spacing;
  const GradientFieldParams cases[] = {{1.5, 0.0},
                                       {1.5, 0.55 * spacing.minCoeff()},
                                       {1.5, 0.5 * (spacing.minCoeff() + spacing.maxCoeff()), true}};
  for (const GradientFieldParams& p : cases) {
    const double resample = p.resample_spacing_mm;
    const auto ref = reference_->download_gradient(*reference_->gradient_field(*reference_->upload(scene_().mu), p));
    const auto got = backend_->download_gradient(*backend_->gradient_field(*backend_->upload(scene_().mu), p));
    ASSERT_EQ(got.geometry.size, ref.geometry.size);
    ASSERT_TRUE(got.geometry.origin.isApprox(ref.geometry.origin, 1e-9));
    ASSERT_TRUE(got.geometry.spacing.isApprox(ref.geometry.spacing, 1e-12));
    if (p.keep_coarser_axes) {
      for (int a = 0; a < 3; ++a) EXPECT_EQ(got.geometry.spacing[a], std::max(resample, spacing[a])) << "axis " << a;
    }
    double max_ref = 0, max_err = 0;
    for (size_t i = 0; i < ref.vectors.size(); ++i)
      for (int c = 0; c < 3; ++c) {
        ASSERT_TRUE(std::isfinite(got.vectors[i][size_t(c)]));
        max_ref = std::max(max_ref, double(std::abs(ref.vectors[i][size_t(c)])));
        max_err = std::max(max_err, double(std::abs(got.vectors[i][size_t(c)] - ref.vectors[i][size_t(c)])));
      }
    EXPECT_GT(max_ref, 0);
    // The cpu backend keeps volumes and fields as 16-bit fixed point (1.5e-5 of the largest
    // magnitude each): the field carries both roundings.
    EXPECT_LT(max_err, 1e-4 * max_ref) << "resample " << resample;
  }
}

TEST_P(BackendEquivalence, Drr) {
  if (skip_unless(Op::drr)) GTEST_SKIP() << "drr not supported";
  const Scene& s = scene_();
  const DrrParams p{0.8, {}};
  const auto ref = reference_->drr(*reference_->upload(s.mu), s.poses, s.views, p);
  const auto got = backend_->drr(*backend_->upload(s.mu), s.poses, s.views, p);
  ASSERT_EQ(got.size(), s.poses.size() * s.views.size());
  for (size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(got[i].width, ref[i].width);
    ASSERT_EQ(got[i].height, ref[i].height);
    double max_ref = 0, max_err = 0;
    for (size_t k = 0; k < got[i].pixels.size(); ++k) {
      ASSERT_TRUE(std::isfinite(got[i].pixels[k]));
      max_ref = std::max(max_ref, double(ref[i].pixels[k]));
      max_err = std::max(max_err, double(std::abs(got[i].pixels[k] - ref[i].pixels[k])));
    }
    EXPECT_GT(max_ref, 0.05) << "image " << i;
    EXPECT_LT(max_err, 1e-4 * max_ref) << "image " << i;
  }
}

TEST_P(BackendEquivalence, DrrWindowIsTheMatchingPartOfTheWholeImage) {
  if (skip_unless(Op::drr)) GTEST_SKIP() << "drr not supported";
  const Scene& s = scene_();
  const PinholeCamera& cam = s.views[0];
  const PixelWindow w{3, 5, cam.width - 7, cam.height - 11};
  const auto whole = reference_->drr(*reference_->upload(s.mu), s.poses, std::span(&cam, 1), DrrParams{0.8, {}});
  const auto part = backend_->drr(*backend_->upload(s.mu), s.poses, std::span(&cam, 1), DrrParams{0.8, w});
  for (size_t p = 0; p < s.poses.size(); ++p) {
    ASSERT_EQ(part[p].width, w.width);
    ASSERT_EQ(part[p].height, w.height);
    for (int y = 0; y < w.height; ++y)
      for (int x = 0; x < w.width; ++x)
        ASSERT_NEAR(part[p].at(x, y), whole[p].at(x + w.x0, y + w.y0), 1e-4 * (1 + whole[p].at(x + w.x0, y + w.y0)));
  }
}

TEST_P(BackendEquivalence, GradientProjection) {
  if (skip_unless(Op::gradient_projection)) GTEST_SKIP() << "gradient_projection not supported";
  const Scene& s = scene_();
  const auto edges = edge_pixels_for(s);
  std::vector<std::vector<Eigen::Vector2f>> pixels;
  for (const auto& e : edges) pixels.push_back(e.pixels);
  // Trilinear on the volume's grid, and the seed's nearest-voxel reads of a resampled field.
  const double fine = 0.7 * s.mu.geometry.spacing.minCoeff();  // a finer grid, as the seed's 0.5 mm
  for (const auto& [sampling, resample] : {std::pair{Sampling::trilinear, 0.0}, std::pair{Sampling::nearest, fine}}) {
    const GradientFieldParams fp{1.0, resample};
    const ProjectionParams pp{0.9, sampling};
    const auto ref = reference_->gradient_projection(*reference_->gradient_field(*reference_->upload(s.mu), fp),
                                                     s.poses, s.views, pixels, pp);
    const auto got = backend_->gradient_projection(*backend_->gradient_field(*backend_->upload(s.mu), fp), s.poses,
                                                   s.views, pixels, pp);
    ASSERT_EQ(got.size(), ref.size());
    double max_ref = 0, max_err = 0, sum_ref2 = 0, sum_err2 = 0;
    for (size_t i = 0; i < got.size(); ++i) {
      ASSERT_EQ(got[i].size(), ref[i].size());
      for (size_t k = 0; k < got[i].size(); ++k) {
        ASSERT_TRUE(got[i][k].allFinite());
        max_ref = std::max(max_ref, double(ref[i][k].norm()));
        max_err = std::max(max_err, double((got[i][k] - ref[i][k]).norm()));
        sum_ref2 += ref[i][k].squaredNorm();
        sum_err2 += (got[i][k] - ref[i][k]).squaredNorm();
      }
    }
    EXPECT_GT(max_ref, 0);
    if (sampling == Sampling::trilinear) {
      EXPECT_LT(max_err, 1e-4 * max_ref);
    } else {
      // A nearest read flips to the neighbouring voxel where float and double positions straddle
      // a voxel boundary: rare, but one flip moves a pixel by a voxel's gradient step. Relative
      // L2 over all pixels, and a loose bound on the worst one.
      EXPECT_LT(std::sqrt(sum_err2 / sum_ref2), 1e-2);
      EXPECT_LT(max_err, 0.05 * max_ref);
    }
  }
}

// Op::gradient_floor, and the marchers' skipping of the space it empties: the backend's floored
// field read through the gradient projection, against the reference floor of the backend's own
// (unfloored) field. The same field on both sides: the fields themselves differ by up to 1e-4 of
// the largest magnitude (GradientField above), so a voxel that close to the floor may be kept by
// one backend and zeroed by the other, each such voxel moving a pixel by at most the floor's bound
// (engine/ops.hpp); here the op alone is compared, with the gradient projection's tolerance.
TEST_P(BackendEquivalence, GradientProjectionOfFlooredField) {
  if (skip_unless(Op::gradient_floor) || skip_unless(Op::gradient_projection)) GTEST_SKIP() << "gradient_floor not supported";
  const Scene& s = scene_();
  std::vector<std::vector<Eigen::Vector2f>> pixels;
  for (const auto& e : edge_pixels_for(s)) pixels.push_back(e.pixels);
  const GradientFloorParams floor{0.1};
  const ProjectionParams pp{0.9, Sampling::trilinear};
  const auto field = backend_->gradient_field(*backend_->upload(s.mu), {1.0, 0.0});
  const auto ref_field = reference_->upload(backend_->download_gradient(*field));
  const auto ref = reference_->gradient_projection(*reference_->floor_gradient(*ref_field, floor), s.poses, s.views, pixels, pp);
  const auto unfloored = reference_->gradient_projection(*ref_field, s.poses, s.views, pixels, pp);
  const auto got = backend_->gradient_projection(*backend_->floor_gradient(*field, floor), s.poses, s.views, pixels, pp);
  ASSERT_EQ(got.size(), ref.size());
  double max_ref = 0, max_err = 0, max_floor_change = 0;
  for (size_t i = 0; i < got.size(); ++i)
    for (size_t k = 0; k < got[i].size(); ++k) {
      ASSERT_TRUE(got[i][k].allFinite());
      max_ref = std::max(max_ref, double(ref[i][k].norm()));
      max_err = std::max(max_err, double((got[i][k] - ref[i][k]).norm()));
      max_floor_change = std::max(max_floor_change, double((unfloored[i][k] - ref[i][k]).norm()));
    }
  // The floor matters here (so agreeing on it means something), and both backends agree on it.
  EXPECT_GT(max_floor_change, 1e-3 * max_ref);
  EXPECT_LT(max_err, 1e-4 * max_ref);
}

TEST_P(BackendEquivalence, GprScore) {
  if (skip_unless(Op::gpr_score)) GTEST_SKIP() << "gpr_score not supported";
  const Scene& s = scene_();
  const auto edges = edge_pixels_for(s);
  const GprParams p{{0.9, Sampling::trilinear}, 40.0};
  const auto ref = reference_->gpr_score(*reference_->gradient_field(*reference_->upload(s.mu), {1.0, 0}), s.poses,
                                         s.views, edges, p);
  const auto got = backend_->gpr_score(*backend_->gradient_field(*backend_->upload(s.mu), {1.0, 0}), s.poses,
                                       s.views, edges, p);
  ASSERT_EQ(got.size(), s.poses.size());
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_GT(ref[i], 0);
    // A pixel near the angle threshold may flip between float and double; allow for a few.
    EXPECT_NEAR(got[i], ref[i], 2e-3 * ref[i]) << "pose " << i;
  }
}

// Views with 0, 1, 64 and 65 edge pixels: per-view partial sums must land on the right pose.
TEST_P(BackendEquivalence, GprScoreWithUnevenViews) {
  if (skip_unless(Op::gpr_score)) GTEST_SKIP() << "gpr_score not supported";
  const Scene& s = scene_();
  const auto all = edge_pixels_for(s);
  std::vector<PinholeCamera> views;
  std::vector<EdgePixels> edges;
  for (const size_t n : {size_t(0), size_t(1), size_t(64), size_t(65)}) {
    views.push_back(s.views[n % s.views.size()]);
    EdgePixels e;
    e.pixels.assign(all[0].pixels.begin(), all[0].pixels.begin() + std::ptrdiff_t(n));
    e.directions.assign(all[0].directions.begin(), all[0].directions.begin() + std::ptrdiff_t(n));
    edges.push_back(e);
  }
  const GprParams p{{0.9, Sampling::trilinear}, 60.0};
  const auto ref = reference_->gpr_score(*reference_->gradient_field(*reference_->upload(s.mu), {1.0, 0}), s.poses,
                                         views, edges, p);
  const auto got = backend_->gpr_score(*backend_->gradient_field(*backend_->upload(s.mu), {1.0, 0}), s.poses,
                                       views, edges, p);
  ASSERT_EQ(got.size(), s.poses.size());
  for (size_t i = 0; i < got.size(); ++i) EXPECT_NEAR(got[i], ref[i], 2e-3 * ref[i] + 1e-9) << "pose " << i;
}

TEST_P(BackendContract, MismatchedBatchesAreBadInput) {
  const Scene& s = scene_();
  const auto grad = backend_->gradient_field(*backend_->upload(s.mu), {1.0, 0});
  auto edges = edge_pixels_for(s);
  edges[0].directions.pop_back();
  EXPECT_THROW(backend_->gpr_score(*grad, s.poses, s.views, edges, {}), InputError);
  edges.pop_back();
  EXPECT_THROW(backend_->gpr_score(*grad, s.poses, s.views, edges, {}), InputError);
  std::vector<std::vector<Eigen::Vector2f>> pixels(s.views.size(), {Eigen::Vector2f(1, std::nanf(""))});
  EXPECT_THROW(backend_->gradient_projection(*grad, s.poses, s.views, pixels, {}), InputError);
  EXPECT_THROW(backend_->drr(*backend_->upload(s.mu), s.poses, s.views, DrrParams{1e-9, {}}), InputError);
}

TEST_P(BackendContract, EmptyBatchesGiveEmptyResults) {
  if (skip_unless(Op::gpr_score)) GTEST_SKIP() << "gpr_score not supported";
  const Scene& s = scene_();
  const auto mu = backend_->upload(s.mu);
  EXPECT_TRUE(backend_->drr(*mu, {}, s.views, {}).empty());
  EXPECT_TRUE(backend_->gpr_score(*backend_->gradient_field(*mu, {}), {}, s.views, edge_pixels_for(s), {}).empty());
}

// Threads calling ops at once on one backend, sharing its volumes (as a sweep's runs do), get
// exactly what the same calls give one after another.
TEST_P(BackendContract, ConcurrentCallsGiveTheSerialResults) {
  const Scene& s = scene_();
  const auto mu = backend_->upload(s.mu);
  const auto grad = backend_->gradient_field(*mu, {1.0, 0});
  const auto edges = edge_pixels_for(s);
  const auto serial_scores = backend_->gpr_score(*grad, s.poses, s.views, edges, {});
  const auto serial_drrs = backend_->drr(*mu, s.poses, s.views, DrrParams{1.0, {}});
  constexpr int kThreads = 3;
  std::vector<std::vector<double>> scores(kThreads);
  std::vector<std::vector<Image>> drrs(kThreads);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&, t] {
      scores[size_t(t)] = backend_->gpr_score(*grad, s.poses, s.views, edges, {});
      drrs[size_t(t)] = backend_->drr(*mu, s.poses, s.views, DrrParams{1.0, {}});
    });
  for (auto& th : threads) th.join();
  for (int t = 0; t < kThreads; ++t) {
    EXPECT_EQ(scores[size_t(t)], serial_scores) << "thread " << t;
    ASSERT_EQ(drrs[size_t(t)].size(), serial_drrs.size());
    for (size_t i = 0; i < serial_drrs.size(); ++i) EXPECT_EQ(drrs[size_t(t)][i].pixels, serial_drrs[i].pixels);
  }
}

// A backend that only renders DRRs: the other ops are refused by the interface before any
// implementation runs, with a message naming the op (ggml's supports_op contract).
class DrrOnlyBackend final : public Backend {
 public:
  std::string_view name() const override { return "drr-only"; }
  bool supports(Op op) const override { return op == Op::drr; }

 protected:
  std::shared_ptr<const DeviceVolume> upload_impl(const Volume& mu) override {
    return std::make_shared<DeviceVolume>(mu.geometry, 1, this);
  }
  std::shared_ptr<const DeviceVolume> upload_impl(const VectorField& g) override {
    return std::make_shared<DeviceVolume>(g.geometry, 3, this);
  }
  VectorField download_gradient_impl(const DeviceVolume&) override { throw std::logic_error("not reached"); }
  std::shared_ptr<const DeviceVolume> gradient_field_impl(const DeviceVolume&, const GradientFieldParams&) override {
    throw std::logic_error("not reached");
  }
  std::vector<Image> drr_impl(const DeviceVolume&, std::span<const Pose> poses, std::span<const PinholeCamera> views,
                              const DrrParams&) override {
    return std::vector<Image>(poses.size() * views.size(), Image(views[0].width, views[0].height));
  }
  std::vector<std::vector<Eigen::Vector2f>> gradient_projection_impl(const DeviceVolume&, std::span<const Pose>,
                                                                     std::span<const PinholeCamera>,
                                                                     std::span<const std::vector<Eigen::Vector2f>>,
                                                                     const ProjectionParams&) override {
    throw std::logic_error("not reached");
  }
  std::vector<double> gpr_score_impl(const DeviceVolume&, std::span<const Pose>, std::span<const PinholeCamera>,
                                     std::span<const EdgePixels>, const GprParams&) override {
    throw std::logic_error("not reached");
  }
};

TEST(BackendInterface, UnsupportedOpsAreRefusedNamingTheOp) {
  DrrOnlyBackend b;
  const Scene& s = scene(1);
  const auto mu = b.upload(s.mu);
  EXPECT_EQ(b.drr(*mu, s.poses, s.views, DrrParams{1.0, {}}).size(), s.poses.size() * s.views.size());
  try {
    b.gradient_field(*mu, {});
    ADD_FAILURE() << "gradient_field ran on a backend that does not support it";
  } catch (const BackendUnavailable& e) {
    EXPECT_NE(std::string(e.what()).find("drr-only: gradient_field is not supported"), std::string::npos) << e.what();
  }
  VectorField field;
  field.geometry = s.mu.geometry;
  field.vectors.assign(s.mu.voxels.size(), {0.f, 0.f, 0.f});
  const auto g = b.upload(field);
  EXPECT_THROW(b.gpr_score(*g, s.poses, s.views, edge_pixels_for(s), {}), BackendUnavailable);
  const std::vector<std::vector<Eigen::Vector2f>> pixels(s.views.size(), {Eigen::Vector2f(1, 1)});
  EXPECT_THROW(b.gradient_projection(*g, s.poses, s.views, pixels, {}), BackendUnavailable);
}

std::vector<std::string> all_backends_but_reference() {
  std::vector<std::string> names;
  for (const auto& n : backend_names())
    if (n != "reference") names.push_back(n);
  return names;
}

const auto kParamName = [](const auto& info) {
  return std::get<0>(info.param) + "_" + scene(std::get<1>(info.param)).name;
};
INSTANTIATE_TEST_SUITE_P(AllBackends, BackendEquivalence,
                         ::testing::Combine(::testing::ValuesIn(all_backends_but_reference()), ::testing::Values(0, 1, 2)),
                         kParamName);
INSTANTIATE_TEST_SUITE_P(AllBackends, BackendContract,
                         ::testing::Combine(::testing::ValuesIn(backend_names()), ::testing::Values(0, 1)), kParamName);

// The real pelvis CT (LPS direction diag(-1, -1, 1) through ITK): every other backend (cpu, and
// vulkan where a device exists) against reference.
TEST(RealCt, DrrMatchesReferenceOnThePelvis) {
  const std::string path = std::string(FLUORO_SHARED_DATASETS) + "/pelvis-ct/ct.nii.gz";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "no " << path << " (the shared datasets are absent)";
  const Volume mu = hu_to_attenuation(read_volume(path));
  ASSERT_NEAR(mu.geometry.direction(0, 0), -1, 1e-9);
  CArmGeometry g;
  g.pixels = 64;
  g.pixel_mm = 4.0;
  // The volume is not centred on the world origin: centre it with the pose.
  Pose pose = Pose::Identity();
  pose.translation() = -mu.geometry.physical_centre();
  const PinholeCamera views[] = {c_arm_view(g, 0), c_arm_view(g, 90)};
  auto ref = make_backend("reference");
  const auto a = ref->drr(*ref->upload(mu), std::span(&pose, 1), views, DrrParams{1.0, {}});
  for (const auto& name : backend_names()) {
    if (name == "reference") continue;
    std::unique_ptr<Backend> other;
    try {
      other = make_backend(name);
    } catch (const BackendUnavailable& e) {  // built in, no device here
      std::printf("skipping %s: %s\n", name.c_str(), e.what());
      continue;
    }
    const auto b = other->drr(*other->upload(mu), std::span(&pose, 1), views, DrrParams{1.0, {}});
    for (size_t i = 0; i < 2; ++i) {
      float max_v = 0, max_err = 0;
      for (size_t k = 0; k < a[i].pixels.size(); ++k) {
        max_v = std::max(max_v, a[i].pixels[k]);
        max_err = std::max(max_err, std::abs(a[i].pixels[k] - b[i].pixels[k]));
      }
      EXPECT_GT(max_v, 1.0) << name;  // a real body: several units of line integral
      EXPECT_LT(max_err, 1e-4f * max_v) << name;
    }
  }
}

}  // namespace
}  // namespace fluoro
