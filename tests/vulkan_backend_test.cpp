// The vulkan backend beyond the equivalence suite: device listing and choice, clear errors for
// bad device names, limits handled (volumes refused, batches split at the device's limits),
// guard bands, exactness of the hardware trilinear filter, and tiny and odd sizes. Without a
// Vulkan driver every test skips with the reason; without the backend built, none is compiled.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <optional>

#include "engine/backend.hpp"
#include "engine/error.hpp"
#include "kernels/backend_registry.hpp"
#include "tests/test_scenes.hpp"

#if FLUORO_HAVE_VULKAN
#include "kernels/vulkan/vulkan_backend.hpp"
#include "kernels/vulkan/vulkan_context.hpp"
#include "kernels/vulkan/vulkan_volume.hpp"

namespace fluoro {
namespace {

// The default device's backend, or a skip naming why there is none.
#define VULKAN_OR_SKIP(var, ...)                                                  \
  std::unique_ptr<Backend> var;                                                   \
  try {                                                                           \
    var = vulkan::make_vulkan_backend(0 __VA_OPT__(, ) __VA_ARGS__);              \
  } catch (const BackendUnavailable& e) {                                         \
    GTEST_SKIP() << e.what();                                                     \
  }

vulkan::Limits device_limits() { return vulkan::list_devices().at(0).limits; }

Volume blob_volume(Eigen::Vector3i n, Eigen::Vector3d s = {1.3, 0.9, 1.1}) {
  return test::make_volume(n, s, [](const Eigen::Vector3d& x) {
    return float(0.02 * std::exp(-x.squaredNorm() / 50.0) + 0.01 * (x.x() > 1.0));
  });
}

std::vector<EdgePixels> spread_edges(const PinholeCamera& cam, int count) {
  EdgePixels e;
  for (int i = 0; i < count; ++i) {
    e.pixels.emplace_back(float((i * 7) % cam.width) + 0.3f, float((i * 11) % cam.height) + 0.6f);
    e.directions.emplace_back(std::cos(0.4f * float(i)), std::sin(0.4f * float(i)));
  }
  return {e};
}

TEST(VulkanBackend, ListsDevicesWithTheirLimits) {
  std::vector<vulkan::DeviceInfo> devices;
  try {
    devices = vulkan::list_devices();
  } catch (const BackendUnavailable& e) {
    GTEST_SKIP() << e.what();
  }
  if (devices.empty()) GTEST_SKIP() << "no Vulkan device";
  for (const auto& d : devices) {
    EXPECT_FALSE(d.name.empty());
    EXPECT_FALSE(d.type.empty());
    EXPECT_GT(d.limits.max_image_dimension_3d, 0u);
    EXPECT_GT(d.limits.max_storage_buffer_range, 0u);
    EXPECT_GT(d.limits.max_group_count_x, 0u);
  }
}

TEST(VulkanBackend, DeviceNamesAreCheckedWithClearMessages) {
  VULKAN_OR_SKIP(b);
  EXPECT_EQ(make_backend("vulkan:0")->name(), "vulkan");
  try {
    make_backend("vulkan:99");
    FAIL() << "vulkan:99 accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no Vulkan device 99"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("found"), std::string::npos) << e.what();
  }
  EXPECT_THROW(make_backend("vulkan:x"), InputError);
  EXPECT_THROW(make_backend("vulkan:-1"), InputError);
  EXPECT_THROW(make_backend("cpu:1"), InputError);  // the other backends take no option
}

TEST(VulkanBackend, VolumesBeyondTheDeviceLimitsAreRefused) {
  vulkan::Limits small;
  try {
    small = device_limits();
  } catch (const BackendUnavailable& e) {
    GTEST_SKIP() << e.what();
  }
  small.max_image_dimension_3d = 16;
  // Eight 13 x 12 float slices: less than one slice with its halo of 4 on either side (sigma 1 mm
  // on 1.1 mm voxels), so the gradient field cannot even be split into slabs.
  small.max_storage_buffer_range = 8 * 13 * 12 * 4;
  VULKAN_OR_SKIP(b, small);
  try {
    b->upload(blob_volume({17, 4, 4}));
    FAIL() << "a 17-voxel side accepted with a 16-voxel limit";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("largest 3D image (16"), std::string::npos) << e.what();
  }
  const auto mu = b->upload(blob_volume({13, 12, 12}));  // fits the image, not the buffers
  try {
    b->gradient_field(*mu, {1.0, 0.0});
    FAIL() << "gradient field beyond the storage-buffer range accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("largest storage buffer"), std::string::npos) << e.what();
  }
  // Resampling to a grid past the image limit is refused too.
  const auto small_mu = b->upload(blob_volume({10, 10, 10}, {1, 1, 1}));
  EXPECT_THROW(b->gradient_field(*small_mu, {1.0, 0.5}), InputError);
  EXPECT_NO_THROW(b->gradient_field(*small_mu, {1.0, 0.0}));
}

// A batch whose buffers exceed the largest allocation is refused with the sizes, not attempted.
TEST(VulkanBackend, BatchesBeyondTheLargestAllocationAreRefused) {
  vulkan::Limits small;
  try {
    small = device_limits();
  } catch (const BackendUnavailable& e) {
    GTEST_SKIP() << e.what();
  }
  small.max_allocation = 64 << 10;  // 64 KiB: a 10^3 volume fits, 48-byte rays for 40^2 pixels do not
  VULKAN_OR_SKIP(b, small);
  const auto mu = b->upload(blob_volume({10, 10, 10}));
  const PinholeCamera cam = test::camera_looking_at_origin(100, 100, 40, 40);
  const Pose id = Pose::Identity();
  try {
    b->drr(*mu, std::span(&id, 1), std::span(&cam, 1), {1.0, {}});
    FAIL() << "a batch beyond the allocation limit accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("largest allocation"), std::string::npos) << e.what();
  }
}

// A gradient field whose intermediate buffers exceed the storage-buffer range is computed in
// slabs of slices with a halo of the z filter's radius: the same field, bit for bit, with and
// without resampling.
TEST(VulkanBackend, GradientFieldsAreSplitIntoSlabsAtTheBufferLimit) {
  vulkan::Limits small;
  try {
    small = device_limits();
  } catch (const BackendUnavailable& e) {
    GTEST_SKIP() << e.what();
  }
  const Volume v = blob_volume({21, 17, 39}, {1.1, 0.9, 1.3});
  VULKAN_OR_SKIP(whole);
  for (const int slices : {11, 12, 20}) {  // radius 4 at sigma 1.2 mm: slabs of 3, 4 and 12 slices
    small.max_storage_buffer_range = uint64_t(slices) * 21 * 17 * 4;
    VULKAN_OR_SKIP(split, small);
    for (const double resample : {0.0, 0.8}) {
      const auto a = whole->download_gradient(*whole->gradient_field(*whole->upload(v), {1.2, resample}));
      const auto b = split->download_gradient(*split->gradient_field(*split->upload(v), {1.2, resample}));
      ASSERT_EQ(a.vectors.size(), b.vectors.size());
      for (size_t i = 0; i < a.vectors.size(); ++i) ASSERT_EQ(a.vectors[i], b.vectors[i]) << slices << " slices, voxel " << i;
    }
  }
}

// Batches larger than one dispatch may carry (workgroup count, storage-buffer range) are split
// into several dispatches with the same results, bit for bit.
TEST(VulkanBackend, BatchesAreSplitAtTheDeviceLimits) {
  vulkan::Limits small;
  try {
    small = device_limits();
  } catch (const BackendUnavailable& e) {
    GTEST_SKIP() << e.what();
  }
  small.max_group_count_x = 3;  // 192 rays per dispatch
  VULKAN_OR_SKIP(whole);
  VULKAN_OR_SKIP(split, small);
  const Volume mu = blob_volume({19, 23, 17});
  const PinholeCamera cam = test::camera_looking_at_origin(200, 250, 29, 31);
  const Pose poses[] = {Pose::Identity(), pose_from_rotation_vector(Eigen::Vector3d(0.1, 0.2, -0.1), Eigen::Vector3d(1, 2, 0))};
  const auto a = whole->drr(*whole->upload(mu), poses, std::span(&cam, 1), {0.7, {}});
  const auto b = split->drr(*split->upload(mu), poses, std::span(&cam, 1), {0.7, {}});
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) EXPECT_EQ(a[i].pixels, b[i].pixels);
  const auto edges = spread_edges(cam, 500);
  const auto ga = whole->gradient_field(*whole->upload(mu), {1.0, 0.0});
  const auto gb = split->gradient_field(*split->upload(mu), {1.0, 0.0});
  const std::vector<std::vector<Eigen::Vector2f>> pixels{edges[0].pixels};
  const auto pa = whole->gradient_projection(*ga, poses, std::span(&cam, 1), pixels, {0.8, Sampling::trilinear});
  const auto pb = split->gradient_projection(*gb, poses, std::span(&cam, 1), pixels, {0.8, Sampling::trilinear});
  for (size_t i = 0; i < pa.size(); ++i)
    for (size_t k = 0; k < pa[i].size(); ++k) EXPECT_EQ(pa[i][k], pb[i][k]);
  const GprParams gp{{0.8, Sampling::trilinear}, 45.0};
  EXPECT_EQ(whole->gpr_score(*ga, poses, std::span(&cam, 1), edges, gp),
            split->gpr_score(*gb, poses, std::span(&cam, 1), edges, gp));
}

// Output counts around the workgroup size (1, 63, 64, 65 rays, a 1 x 1 image): every result
// equals the reference's and no shader writes past its outputs (the backend checks a guard
// band after every run and throws if it was touched).
TEST(VulkanBackend, OddSizesAndGuardBands) {
  VULKAN_OR_SKIP(b);
  auto ref = make_backend("reference");
  const Volume mu = blob_volume({7, 5, 3}, {3, 4, 5});
  for (const int side : {1, 8, 9}) {
    const PinholeCamera cam = test::camera_looking_at_origin(150, 400, side, side);
    const auto got = b->drr(*b->upload(mu), std::span<const Pose>(), std::span(&cam, 1), {0.5, {}});
    EXPECT_TRUE(got.empty());
    const Pose id = Pose::Identity();
    const auto g = b->drr(*b->upload(mu), std::span(&id, 1), std::span(&cam, 1), {0.5, {}});
    const auto r = ref->drr(*ref->upload(mu), std::span(&id, 1), std::span(&cam, 1), {0.5, {}});
    for (size_t k = 0; k < r[0].pixels.size(); ++k) EXPECT_NEAR(g[0].pixels[k], r[0].pixels[k], 1e-5 + 1e-5 * r[0].pixels[k]);
  }
  const PinholeCamera cam = test::camera_looking_at_origin(150, 400, 33, 35);
  const Pose id = Pose::Identity();
  const auto gf = b->gradient_field(*b->upload(mu), {2.0, 0.0});
  const auto rf = ref->gradient_field(*ref->upload(mu), {2.0, 0.0});
  for (const int n : {1, 63, 64, 65}) {
    const auto edges = spread_edges(cam, n);
    const std::vector<std::vector<Eigen::Vector2f>> pixels{edges[0].pixels};
    const auto g = b->gradient_projection(*gf, std::span(&id, 1), std::span(&cam, 1), pixels, {0.5, Sampling::trilinear});
    const auto r = ref->gradient_projection(*rf, std::span(&id, 1), std::span(&cam, 1), pixels, {0.5, Sampling::trilinear});
    ASSERT_EQ(g[0].size(), size_t(n));
    double max_ref = 1e-12, max_err = 0;
    for (int k = 0; k < n; ++k) {
      max_ref = std::max(max_ref, double(r[0][size_t(k)].norm()));
      max_err = std::max(max_err, double((g[0][size_t(k)] - r[0][size_t(k)]).norm()));
    }
    EXPECT_LT(max_err, 1e-4 * max_ref) << n << " pixels";
    const GprParams gp{{0.5, Sampling::trilinear}, 50.0};
    const double sg = b->gpr_score(*gf, std::span(&id, 1), std::span(&cam, 1), edges, gp)[0];
    const double sr = ref->gpr_score(*rf, std::span(&id, 1), std::span(&cam, 1), edges, gp)[0];
    EXPECT_NEAR(sg, sr, 2e-3 * sr + 1e-9) << n << " pixels";
  }
  // A one-voxel volume and a one-voxel-thick slab: the filters clamp at every edge.
  for (const Eigen::Vector3i& n : {Eigen::Vector3i(1, 1, 1), Eigen::Vector3i(6, 1, 5)}) {
    const Volume v = blob_volume(n);
    const auto g = b->download_gradient(*b->gradient_field(*b->upload(v), {1.0, 0.0}));
    const auto r = ref->download_gradient(*ref->gradient_field(*ref->upload(v), {1.0, 0.0}));
    for (size_t i = 0; i < r.vectors.size(); ++i)
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(g.vectors[i][size_t(c)], r.vectors[i][size_t(c)], 1e-6);
  }
}

// Trilinear reads must be true trilinear interpolation: a linear ramp sampled off the voxel
// centres comes back exactly (to float rounding), through the path the backend chose for the
// device (the hardware filter where it measured exact, by hand elsewhere) and through the by-hand
// path forced. A filter with 8-bit weights (subTexelPrecisionBits = 8, most GPUs) would be off by
// up to 1/512 of a voxel step.
TEST(VulkanBackend, TrilinearReadsAreExactOnRamps) {
  vulkan::Limits by_hand;
  try {
    by_hand = device_limits();
  } catch (const BackendUnavailable& e) {
    GTEST_SKIP() << e.what();
  }
  by_hand.manual_trilinear = true;
  auto ref = make_backend("reference");
  const Volume ramp = test::make_volume({16, 16, 16}, {1, 1, 1}, [](const Eigen::Vector3d& x) {
    return float(1.0 + 0.05 * x.x() + 0.03 * x.y() - 0.02 * x.z());
  });
  const PinholeCamera cam = test::camera_looking_at_origin(100, 300, 21, 19, Eigen::Vector3d(0.3, 0.5, 1));
  const Pose id = Pose::Identity();
  const auto r = ref->drr(*ref->upload(ramp), std::span(&id, 1), std::span(&cam, 1), {0.37, {}});
  for (const bool forced : {false, true}) {
    VULKAN_OR_SKIP(b, forced ? std::optional(by_hand) : std::nullopt);
    const auto g = b->drr(*b->upload(ramp), std::span(&id, 1), std::span(&cam, 1), {0.37, {}});
    double max_rel = 0;
    for (size_t k = 0; k < r[0].pixels.size(); ++k)
      if (r[0].pixels[k] > 1) max_rel = std::max(max_rel, std::abs(double(g[0].pixels[k]) / r[0].pixels[k] - 1));
    RecordProperty(forced ? "max_relative_error_by_hand" : "max_relative_error", std::to_string(max_rel));
    EXPECT_LT(max_rel, 2e-6) << (forced ? "by hand" : "as chosen for the device");
  }
}

// The filter probe: the by-hand path is exact to float rounding, the device's own filter is
// measured (and lies within what 8-bit weights allow, or the device is broken), and every op
// that reads trilinearly (the resampling of a gradient field, the GPR score) gives the same
// result by hand as through the path chosen for the device.
TEST(VulkanBackend, TheLinearFilterIsMeasuredAndTheByHandPathAgrees) {
  vulkan::Limits by_hand;
  std::shared_ptr<vulkan::Context> ctx;
  try {
    by_hand = device_limits();
    ctx = vulkan::Context::get(0);
  } catch (const BackendUnavailable& e) {
    GTEST_SKIP() << e.what();
  }
  by_hand.manual_trilinear = true;
  EXPECT_LT(vulkan::measure_linear_filter_error(*ctx, true), 1e-6);
  const double device_error = ctx->linear_filter_error();
  RecordProperty("device_filter_error", std::to_string(device_error));
  RecordProperty("sub_texel_precision_bits", std::to_string(ctx->info().sub_texel_precision_bits));
  EXPECT_LT(device_error, 1.0 / 256);

  VULKAN_OR_SKIP(chosen);
  VULKAN_OR_SKIP(manual, by_hand);
  const Volume vol = blob_volume({24, 20, 22});
  const PinholeCamera cam = test::camera_looking_at_origin(120, 400, 48, 40);
  const auto edges = spread_edges(cam, 300);
  const Pose pose = pose_from_rotation_vector(Eigen::Vector3d(0.1, -0.05, 0.2), Eigen::Vector3d(0.5, -0.3, 0.2));
  const GradientFieldParams fp{1.2, 0.7};  // resampled: the resample shader reads trilinearly
  const auto f1 = chosen->gradient_field(*chosen->upload(vol), fp);
  const auto f2 = manual->gradient_field(*manual->upload(vol), fp);
  const VectorField d1 = chosen->download_gradient(*f1), d2 = manual->download_gradient(*f2);
  ASSERT_EQ(d1.vectors.size(), d2.vectors.size());
  double max_abs = 0, max_diff = 0;
  for (size_t i = 0; i < d1.vectors.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      max_abs = std::max(max_abs, double(std::abs(d1.vectors[i][size_t(c)])));
      max_diff = std::max(max_diff, double(std::abs(d1.vectors[i][size_t(c)] - d2.vectors[i][size_t(c)])));
    }
  EXPECT_GT(max_abs, 0.0);
  EXPECT_LE(max_diff, 1e-5 * max_abs);
  const GprParams gp{{0.5, Sampling::trilinear}, 30.0};
  const double s1 = chosen->gpr_score(*f1, std::span(&pose, 1), std::span(&cam, 1), edges, gp)[0];
  const double s2 = manual->gpr_score(*f2, std::span(&pose, 1), std::span(&cam, 1), edges, gp)[0];
  EXPECT_GT(s1, 0.0);
  EXPECT_NEAR(s2, s1, 1e-4 * s1);
}

// Temporary buffers come from the context's pool: once the first calls have allocated them,
// repeating the same ops (and a smaller batch) allocates no device memory at all.
TEST(VulkanBackend, RepeatedCallsReuseTheirTemporaryBuffers) {
  VULKAN_OR_SKIP(b);
  const auto ctx = vulkan::Context::get(0);
  const auto mu = b->upload(blob_volume({20, 18, 16}));
  const auto field = b->gradient_field(*mu, {1.0, 0.0});
  const PinholeCamera cam = test::camera_looking_at_origin(100, 300, 64, 48);
  const auto edges = spread_edges(cam, 500);
  std::vector<Pose> poses(4, Pose::Identity());
  const auto run = [&](size_t n) {
    b->drr(*mu, std::span(poses.data(), n), std::span(&cam, 1), {0.5, {}});
    b->gpr_score(*field, std::span(poses.data(), n), std::span(&cam, 1), edges, GprParams{});
  };
  run(4);
  const size_t allocated = ctx->buffers_allocated();
  run(4);
  run(3);
  run(4);
  EXPECT_EQ(ctx->buffers_allocated(), allocated);
}

// The distance map against its definition: the Chebyshev distance in bricks to the nearest
// brick within one brick of a flagged one, capped; grids longer than the cap along each axis.
TEST(VulkanBackend, BrickDistancesMatchTheirDefinition) {
  const Eigen::Vector3i nb(41, 19, 23);
  std::vector<uint32_t> flags(size_t(nb.prod()), 0);
  auto at = [&](int x, int y, int z) { return (size_t(z) * size_t(nb.y()) + size_t(y)) * size_t(nb.x()) + size_t(x); };
  flags[at(2, 3, 4)] = flags[at(38, 17, 1)] = flags[at(20, 9, 21)] = 1;
  const auto d = vulkan::brick_distances(flags, nb);
  for (int z = 0; z < nb.z(); ++z)
    for (int y = 0; y < nb.y(); ++y)
      for (int x = 0; x < nb.x(); ++x) {
        int best = vulkan::kMaxBrickDistance;
        for (int c = 0; c < nb.z(); ++c)
          for (int b = 0; b < nb.y(); ++b)
            for (int a = 0; a < nb.x(); ++a)
              if (flags[at(a, b, c)])
                best = std::min(best, std::max(0, std::max({std::abs(a - x), std::abs(b - y), std::abs(c - z)}) - 1));
        ASSERT_EQ(int(d[at(x, y, z)]), best) << x << " " << y << " " << z;
      }
}

// Empty-space skipping is exact: a volume larger than the distance cap along every axis, empty
// but for two small blobs, gives the reference's DRR and gradient projection.
TEST(VulkanBackend, EmptySpaceSkippingIsExact) {
  VULKAN_OR_SKIP(b);
  auto ref = make_backend("reference");
  const Volume mu = test::make_volume({97, 83, 71}, {1, 1, 1}, [](const Eigen::Vector3d& x) {
    return float(0.02 * ((x - Eigen::Vector3d(30, -25, 20)).norm() < 4) + 0.03 * ((x + Eigen::Vector3d(35, -30, 25)).norm() < 3));
  });
  const Pose id = Pose::Identity();
  for (const Eigen::Vector3d& towards : {Eigen::Vector3d(0.1, 0.2, 1), Eigen::Vector3d(1, 0.9, 0.8)}) {
    const PinholeCamera cam = test::camera_looking_at_origin(300, 110, 61, 57, towards);
    const auto g = b->drr(*b->upload(mu), std::span(&id, 1), std::span(&cam, 1), {0.6, {}});
    const auto r = ref->drr(*ref->upload(mu), std::span(&id, 1), std::span(&cam, 1), {0.6, {}});
    float max_ref = 0, max_err = 0;
    for (size_t k = 0; k < r[0].pixels.size(); ++k) {
      max_ref = std::max(max_ref, r[0].pixels[k]);
      max_err = std::max(max_err, std::abs(g[0].pixels[k] - r[0].pixels[k]));
    }
    EXPECT_GT(max_ref, 0.1f);
    EXPECT_LT(max_err, 1e-5f * max_ref);
    std::vector<std::vector<Eigen::Vector2f>> pixels(1);
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x) pixels[0].emplace_back(float(x), float(y));
    const auto gp = b->gradient_projection(*b->gradient_field(*b->upload(mu), {1.0, 0.0}), std::span(&id, 1),
                                           std::span(&cam, 1), pixels, {0.6, Sampling::trilinear});
    const auto rp = ref->gradient_projection(*ref->gradient_field(*ref->upload(mu), {1.0, 0.0}), std::span(&id, 1),
                                             std::span(&cam, 1), pixels, {0.6, Sampling::trilinear});
    double max_g = 0, err_g = 0;
    for (size_t k = 0; k < rp[0].size(); ++k) {
      max_g = std::max(max_g, double(rp[0][k].norm()));
      err_g = std::max(err_g, double((gp[0][k] - rp[0][k]).norm()));
    }
    EXPECT_GT(max_g, 0);
    EXPECT_LT(err_g, 1e-4 * max_g);
  }
}

// A submission that does not finish in time is a one-line error, not a hang, and the device is
// not used again (its own context: the process-wide one stays usable for the other tests).
TEST(VulkanBackend, ASubmissionPastTheTimeLimitIsAnError) {
  ::setenv("FLUORO_VULKAN_TIMEOUT_S", "1e-9", 1);
  std::unique_ptr<Backend> b;
  try {
    b = vulkan::make_vulkan_backend(0, std::nullopt, /*shared_context=*/false);
  } catch (const BackendUnavailable& e) {
    ::unsetenv("FLUORO_VULKAN_TIMEOUT_S");
    GTEST_SKIP() << e.what();
  }
  ::unsetenv("FLUORO_VULKAN_TIMEOUT_S");
  const Volume mu = blob_volume({40, 40, 40}, {1, 1, 1});
  const PinholeCamera cam = test::camera_looking_at_origin(150, 300, 200, 200);
  const Pose id = Pose::Identity();
  try {
    const auto dv = b->upload(mu);
    b->drr(*dv, std::span(&id, 1), std::span(&cam, 1), {0.1, {}});
    FAIL() << "no timeout";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("did not finish within"), std::string::npos) << e.what();
  }
  try {
    b->upload(mu);
    FAIL() << "a timed-out device used again";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("unusable"), std::string::npos) << e.what();
  }
}

TEST(VulkanBackend, HandlesFromAnotherBackendAreRejected) {
  VULKAN_OR_SKIP(b);
  auto cpu = make_backend("cpu");
  const auto mu = cpu->upload(blob_volume({5, 5, 5}));
  EXPECT_THROW(b->gradient_field(*mu, {}), std::invalid_argument);
}

}  // namespace
}  // namespace fluoro
#endif
