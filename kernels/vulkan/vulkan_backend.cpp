// The vulkan backend: the ops of engine/backend.hpp as compute shaders. Per-ray set-up (box
// clipping, sample count and step) is done on the host in double precision by the same code as
// the cpu backend (engine/ray_setup.hpp), in parallel, straight into a mapped buffer; the shaders
// march the rays in float, reading volumes through the hardware's trilinear filter. A batch of
// poses and views is one submission: every (pose, view) image's rays in one dispatch (split only
// where a device limit requires).
#include "kernels/vulkan/vulkan_backend.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <numbers>

#include "engine/error.hpp"
#include "engine/ray_setup.hpp"
#include "kernels/common/gaussian_derivative.hpp"
#include "kernels/common/resample_geometry.hpp"
#include "kernels/vulkan/gpu_params.hpp"
#include "kernels/vulkan/vulkan_volume.hpp"

namespace fluoro::vulkan {
namespace {

constexpr auto kStorage = vk::BufferUsageFlagBits::eStorageBuffer;

gpu::vec4 vec4_of(const Eigen::Vector3d& v, double w = 0) { return {float(v.x()), float(v.y()), float(v.z()), float(w)}; }

gpu::Ray make_ray(const RaySetup& s, double u, double v, double step_mm) {
  const PixelRay r = make_pixel_ray(s, u, v, step_mm);
  gpu::Ray g{};
  if (r.n == 0) return g;
  g.entry_t0 = vec4_of(s.source + r.t0 * r.dir, r.t0);
  g.step_h = vec4_of(r.dir * r.h, r.h);
  g.inv_len = float(r.inv_len);
  g.n = r.n;
  return g;
}

// Where pixel (x, y) of a w x h DRR window goes among the window's rays: bands of 8 rows, within
// a band tiles of 8 columns, within a tile row-major (edge tiles smaller). A workgroup of 64 rays
// is then one 8 x 8 tile, whose rays read nearly the same voxels.
size_t tile_index(int x, int y, int w, int h) {
  const int band = y >> 3, band_h = std::min(8, h - (band << 3));
  const int tile = x >> 3, tile_w = std::min(8, w - (tile << 3));
  return size_t(band) * 8 * size_t(w) + size_t(tile) * 8 * size_t(band_h) + size_t(y & 7) * size_t(tile_w) + size_t(x & 7);
}


// Every output buffer ends in a guard band of sentinels that no shader may touch, checked after
// each run: a shader writing past its outputs (a bounds check lost in an edit) fails loudly
// instead of corrupting memory silently.
constexpr size_t kGuardFloats = 64;
constexpr float kSentinel = -1.2345e-29f;

void fill_guard(const Buffer& b, size_t used_floats) {
  std::fill_n(static_cast<float*>(b.mapped) + used_floats, kGuardFloats, kSentinel);
}

void check_guard(const Buffer& b, size_t used_floats, std::string_view what) {
  const float* g = static_cast<const float*>(b.mapped) + used_floats;
  for (size_t i = 0; i < kGuardFloats; ++i)
    if (g[i] != kSentinel) throw std::logic_error(std::string(what) + ": a shader wrote past its outputs");
}

// A linear filter whose error stays under this (in units of a voxel-to-voxel difference) counts
// as exact: float interpolation errs by about 1e-7, 8-bit weights by up to 2e-3.
constexpr double kExactFilterError = 1e-5;

class VulkanBackend final : public Backend {
 public:
  VulkanBackend(int index, const std::optional<Limits>& limits, bool shared_context)
      : ctx_(shared_context ? Context::get(index) : std::make_shared<Context>(index)),
        limits_(limits ? *limits : ctx_->limits()) {}

  std::string_view name() const override { return "vulkan"; }
  bool supports(Op op) const override { return ctx_->info().supports(op); }
  // A CPU driver (lavapipe) does the work of every pose in the batch, like the cpu backend.
  bool prefers_batches() const override { return ctx_->info().type != "CPU"; }

  std::shared_ptr<const DeviceVolume> upload_impl(const Volume& mu) override {
    validate_volume(mu, "vulkan.upload");
    check_image_size(mu.geometry.size, limits_, "vulkan.upload");
    return guarded("vulkan.upload", [&] {
      return std::make_shared<VulkanVolume>(mu.geometry, 1, this, ctx_, upload_scalar(*ctx_, mu, "vulkan.upload"));
    });
  }

  std::shared_ptr<const DeviceVolume> upload_impl(const VectorField& f) override {
    for (size_t i = 0; i < f.vectors.size(); ++i)
      for (const float c : f.vectors[i])
        if (!std::isfinite(c)) throw InputError("vulkan.upload: gradient vector " + std::to_string(i) + " is not finite");
    check_image_size(f.geometry.size, limits_, "vulkan.upload");
    return guarded("vulkan.upload", [&] {
      return std::make_shared<VulkanVolume>(f.geometry, 3, this, ctx_, upload_field(*ctx_, f, "vulkan.upload"));
    });
  }

  VectorField download_gradient_impl(const DeviceVolume& handle) override {
    const auto& v = static_cast<const VulkanVolume&>(handle);
    return guarded("vulkan.download_gradient", [&] {
      return VectorField{v.geometry(), download_field(*ctx_, v.image(), "vulkan.download_gradient")};
    });
  }

  std::shared_ptr<const DeviceVolume> gradient_field_impl(const DeviceVolume& handle,
                                                          const GradientFieldParams& params) override {
    return guarded("vulkan.gradient_field", [&] { return gradient_field_on_device(static_cast<const VulkanVolume&>(handle), params); });
  }

  std::vector<Image> drr_impl(const DeviceVolume& handle, std::span<const Pose> poses,
                              std::span<const PinholeCamera> views, const DrrParams& params) override {
    return guarded("vulkan.drr", [&] { return drr_on_device(static_cast<const VulkanVolume&>(handle), poses, views, params); });
  }

  std::vector<std::vector<Eigen::Vector2f>> gradient_projection_impl(
      const DeviceVolume& handle, std::span<const Pose> poses, std::span<const PinholeCamera> views,
      std::span<const std::vector<Eigen::Vector2f>> pixels, const ProjectionParams& params) override {
    return guarded("vulkan.gradient_projection", [&] {
      std::vector<std::vector<Eigen::Vector2f>> out(poses.size() * views.size());
      for (size_t i = 0; i < out.size(); ++i) out[i].resize(pixels[i % views.size()].size());
      project(static_cast<const VulkanVolume&>(handle), poses, views, pixels, nullptr, params, 0.0f,
              [&](const Batch& b, const void* result) {
                const auto* g = static_cast<const float*>(result);
                for (size_t i = 0; i < out.size(); ++i) {
                  const auto& order = b.order[i % views.size()];
                  const size_t first = size_t(b.first_group[i]) * gpu::kRayGroup;
                  for (size_t k = 0; k < order.size(); ++k)
                    out[i][order[k]] = Eigen::Vector2f(g[2 * (first + k)], g[2 * (first + k) + 1]);
                }
              });
      return out;
    });
  }

  std::vector<double> gpr_score_impl(const DeviceVolume& handle, std::span<const Pose> poses,
                                     std::span<const PinholeCamera> views, std::span<const EdgePixels> edges,
                                     const GprParams& params) override {
    return guarded("vulkan.gpr_score", [&] {
      std::vector<std::vector<Eigen::Vector2f>> pixels(views.size());
      for (size_t v = 0; v < views.size(); ++v) pixels[v] = edges[v].pixels;
      const float cos_max = float(std::cos(params.max_angle_deg * std::numbers::pi / 180.0));
      std::vector<double> scores(poses.size(), 0.0);
      project(static_cast<const VulkanVolume&>(handle), poses, views, pixels, edges.data(), params.projection, cos_max,
              [&](const Batch& b, const void* result) {
                // Per-workgroup partial sums, added per pose in a fixed order (the same result every run).
                const auto* partial = static_cast<const float*>(result);
                for (size_t i = 0; i < b.first_group.size() - 1; ++i)
                  for (uint32_t g = b.first_group[i]; g < b.first_group[i + 1]; ++g)
                    scores[i / views.size()] += double(partial[g]);
              });
      return scores;
    });
  }

 private:
  // Rays per dispatch: within the workgroup-count limit, the storage-buffer range of the largest
  // per-ray buffer (a Ray), and aligned so each dispatch's buffers start at an allowed offset.
  uint64_t rays_per_dispatch() const {
    const uint64_t unit = std::max<uint64_t>(gpu::kRayGroup, limits_.storage_offset_alignment);
    const uint64_t by_groups = uint64_t(limits_.max_group_count_x) * gpu::kRayGroup;
    const uint64_t by_range = limits_.max_storage_buffer_range / sizeof(gpu::Ray);
    const uint64_t n = std::min(by_groups, by_range) / unit * unit;
    if (n == 0) throw std::runtime_error("vulkan: device limits leave no room for a dispatch of rays");
    return n;
  }

  // A batch's largest buffer (its rays) must fit one allocation: refused with the sizes, not tried.
  void check_batch(size_t rays, const char* what) const {
    const uint64_t bytes = uint64_t(rays) * sizeof(gpu::Ray);
    if (bytes > limits_.max_allocation)
      throw InputError(std::string(what) + ": a batch of " + std::to_string(rays) + " rays needs " +
                       std::to_string(bytes >> 20) + " MiB of ray set-up, more than the device's largest allocation (" +
                       std::to_string(limits_.max_allocation >> 20) + " MiB); split the batch");
  }

  std::vector<Image> drr_on_device(const VulkanVolume& mu, std::span<const Pose> poses,
                                   std::span<const PinholeCamera> views, const DrrParams& params) {
    const size_t n_images = poses.size() * views.size();
    std::vector<Image> out(n_images);
    if (n_images == 0) return out;
    std::vector<RaySetup> setups(n_images);
    std::vector<PixelWindow> windows(n_images);
    std::vector<size_t> first_ray(n_images + 1, 0);
    for (size_t p = 0; p < poses.size(); ++p)
      for (size_t v = 0; v < views.size(); ++v) {
        const size_t i = p * views.size() + v;
        windows[i] = resolve_window(params.window, views[v]);
        setups[i] = make_ray_setup(mu.geometry(), poses[p], views[v]);
        first_ray[i + 1] = first_ray[i] + size_t(windows[i].width) * size_t(windows[i].height);
      }
    const size_t total = first_ray.back();
    check_batch(total, "vulkan.drr");
    const uint64_t chunk = rays_per_dispatch();
    const size_t dispatches = (total + chunk - 1) / chunk;
    Frame frame(*ctx_, uint32_t(dispatches));
    Buffer& rays = frame.temp_buffer(total * sizeof(gpu::Ray), kStorage, true, "vulkan.drr");
    Buffer& sums = frame.temp_buffer((total + kGuardFloats) * sizeof(float), kStorage, true, "vulkan.drr");
    fill_guard(sums, total);
    auto* ray = static_cast<gpu::Ray*>(rays.mapped);
    // One task per image row.
    struct Row { uint32_t image; int y; };
    std::vector<Row> rows;
    for (size_t i = 0; i < n_images; ++i)
      for (int y = 0; y < windows[i].height; ++y) rows.push_back({uint32_t(i), y});
    tbb::parallel_for(size_t(0), rows.size(), [&](size_t r) {
      const Row& row = rows[r];
      const PixelWindow& w = windows[row.image];
      gpu::Ray* dst = ray + first_ray[row.image];
      for (int x = 0; x < w.width; ++x)
        dst[tile_index(x, row.y, w.width, w.height)] = make_ray(setups[row.image], w.x0 + x, w.y0 + row.y, params.step_mm);
    });
    const Pipeline& p = ctx_->pipeline(Shader::drr, manual_trilinear());
    for (size_t d = 0; d < dispatches; ++d) {
      const uint64_t first = d * chunk, count = std::min<uint64_t>(chunk, total - first);
      const gpu::MarchPush push{uint32_t(count), 0, 0.0f, 0};
      frame.bind(p,
                 {Binding::sampled(mu.image(), ctx_->linear_sampler()),
                  Binding::sampled(mu.distance_map(), ctx_->nearest_sampler()),
                  Binding::storage(rays, first * sizeof(gpu::Ray), count * sizeof(gpu::Ray)),
                  Binding::storage(sums, first * sizeof(float), count * sizeof(float))},
                 &push, sizeof(push));
      frame.cmd().dispatch(uint32_t((count + gpu::kRayGroup - 1) / gpu::kRayGroup), 1, 1);
    }
    frame.run("vulkan.drr");
    check_guard(sums, total, "vulkan.drr");
    const auto* s = static_cast<const float*>(sums.mapped);
    for (size_t i = 0; i < n_images; ++i) {
      const int w = windows[i].width, h = windows[i].height;
      out[i] = Image(w, h);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) out[i].at(x, y) = s[first_ray[i] + tile_index(x, y, w, h)];
    }
    return out;
  }

  // The layout of a projection batch: image i (= pose * views + view) owns workgroups
  // [first_group[i], first_group[i + 1]); its ray k (in tile order) is pixel order[view][k].
  struct Batch {
    std::vector<std::vector<uint32_t>> order;
    std::vector<uint32_t> first_group;
  };

  // Runs the gradient projection (edges == nullptr) or the GPR score of a batch and hands the
  // mapped result (vec2 per ray, or a float partial sum per workgroup) to sink(batch, result).
  template <class Sink>
  void project(const VulkanVolume& field, std::span<const Pose> poses, std::span<const PinholeCamera> views,
               std::span<const std::vector<Eigen::Vector2f>> pixels, const EdgePixels* edges,
               const ProjectionParams& params, float cos_max, Sink&& sink) {
    const char* what = edges ? "vulkan.gpr_score" : "vulkan.gradient_projection";
    const size_t n_images = poses.size() * views.size();
    if (n_images == 0) return;
    Batch b;
    b.order.resize(views.size());
    for (size_t v = 0; v < views.size(); ++v) b.order[v] = tile_order(pixels[v]);
    b.first_group.assign(n_images + 1, 0);
    for (size_t i = 0; i < n_images; ++i)
      b.first_group[i + 1] =
          b.first_group[i] + uint32_t((pixels[i % views.size()].size() + gpu::kRayGroup - 1) / gpu::kRayGroup);
    const size_t groups = b.first_group.back();
    if (groups == 0) {
      std::vector<float> none;
      sink(b, none.data());
      return;
    }
    const size_t total = groups * gpu::kRayGroup;
    check_batch(total, what);
    const uint64_t chunk = rays_per_dispatch();
    const size_t dispatches = (total + chunk - 1) / chunk;
    Frame frame(*ctx_, uint32_t(dispatches));
    Buffer& rays = frame.temp_buffer(total * sizeof(gpu::Ray), kStorage, true, what);
    Buffer& images = frame.temp_buffer(n_images * sizeof(gpu::ProjectionImage), kStorage, true, what);
    Buffer& group_image = frame.temp_buffer(groups * sizeof(uint32_t), kStorage, true, what);
    const size_t result_floats = edges ? groups : total * 2;
    Buffer& result = frame.temp_buffer((result_floats + kGuardFloats) * sizeof(float), kStorage, true, what);
    fill_guard(result, result_floats);
    auto* ray = static_cast<gpu::Ray*>(rays.mapped);
    auto* im = static_cast<gpu::ProjectionImage*>(images.mapped);
    auto* gi = static_cast<uint32_t*>(group_image.mapped);
    std::vector<RaySetup> setups(n_images);
    for (size_t i = 0; i < n_images; ++i) {
      setups[i] = make_ray_setup(field.geometry(), poses[i / views.size()], views[i % views.size()]);
      im[i] = {vec4_of(setups[i].axis_u), vec4_of(setups[i].axis_v)};
      for (uint32_t g = b.first_group[i]; g < b.first_group[i + 1]; ++g) gi[g] = uint32_t(i);
    }
    // One task per workgroup of rays (padding rays have n = 0).
    tbb::parallel_for(size_t(0), groups, [&](size_t g) {
      const size_t i = gi[g], v = i % views.size();
      const auto& px = pixels[v];
      const auto& order = b.order[v];
      for (size_t k = (g - b.first_group[i]) * gpu::kRayGroup, j = 0; j < gpu::kRayGroup; ++k, ++j) {
        gpu::Ray& r = ray[g * gpu::kRayGroup + j];
        if (k >= px.size()) {
          r = gpu::Ray{};
          continue;
        }
        const uint32_t pixel = order[k];
        r = make_ray(setups[i], px[pixel].x(), px[pixel].y(), params.step_mm);
        if (edges) {
          r.dir_u = edges[v].directions[pixel].x();
          r.dir_v = edges[v].directions[pixel].y();
        }
      }
    });
    const bool nearest = params.sampling == Sampling::nearest;
    const Pipeline& p = ctx_->pipeline(edges ? (nearest ? Shader::score_nearest : Shader::score_trilinear)
                                             : (nearest ? Shader::projection_nearest : Shader::projection_trilinear),
                                       !nearest && manual_trilinear());  // nearest reads never interpolate
    for (size_t d = 0; d < dispatches; ++d) {
      const uint64_t first = d * chunk, count = std::min<uint64_t>(chunk, total - first);
      const gpu::MarchPush push{uint32_t(count), uint32_t(first / gpu::kRayGroup), cos_max, 0};
      frame.bind(p,
                 {Binding::sampled(field.image(), ctx_->linear_sampler()),
                  Binding::sampled(field.distance_map(), ctx_->nearest_sampler()),
                  Binding::storage(rays, first * sizeof(gpu::Ray), count * sizeof(gpu::Ray)), Binding::storage(images),
                  Binding::storage(group_image),
                  edges ? Binding::storage(result, 0, result_floats * sizeof(float))
                        : Binding::storage(result, first * 2 * sizeof(float), count * 2 * sizeof(float))},
                 &push, sizeof(push));
      frame.cmd().dispatch(uint32_t(count / gpu::kRayGroup), 1, 1);
    }
    frame.run(what);
    check_guard(result, result_floats, what);
    sink(b, result.mapped);
  }

  std::shared_ptr<const DeviceVolume> gradient_field_on_device(const VulkanVolume& mu, const GradientFieldParams& params) {
    const char* what = "vulkan.gradient_field";
    const VolumeGeometry& g = mu.geometry();
    const Eigen::Vector3i n = g.size;
    // The x and y passes stay within a z slice, the z pass reaches f[2].radius slices away: the
    // volume is processed in slabs of whole slices (one slab when it fits), each with a halo of
    // that radius, so that every intermediate buffer fits the storage-buffer range.
    DerivativeFilter f[3];
    std::vector<float> weights;
    int offset[3];
    for (int a = 0; a < 3; ++a) {
      f[a] = make_derivative_filter(params.sigma_mm / g.spacing[a]);
      offset[a] = int(weights.size());
      weights.insert(weights.end(), f[a].smooth.begin(), f[a].smooth.end());
      weights.insert(weights.end(), f[a].derivative.begin(), f[a].derivative.end());
    }
    const int rz = f[2].radius;
    const uint64_t slice_bytes = uint64_t(n.x()) * uint64_t(n.y()) * sizeof(float);
    const uint64_t max_slices = std::min(limits_.max_storage_buffer_range, limits_.max_allocation) / slice_bytes;
    if (max_slices < uint64_t(std::min(n.z(), 1 + 2 * rz)))
      throw InputError(std::string(what) + ": a " + std::to_string(n.x()) + " x " + std::to_string(n.y()) +
                       " slice with a halo of " + std::to_string(rz) + " slices on each side needs more than the device's " +
                       "largest storage buffer binding (" + std::to_string(limits_.max_storage_buffer_range >> 20) +
                       " MiB); crop or resample the volume, or use the cpu backend");
    // Output slices per slab: the whole volume if it fits, else what fits beside the halo.
    const int slab = uint64_t(n.z()) <= max_slices ? n.z() : int(max_slices) - 2 * rz;
    const int slabs = (n.z() + slab - 1) / slab;
    const int held = std::min(n.z(), slab + 2 * rz);  // slices each intermediate buffer holds
    VolumeGeometry out_geometry = g;
    if (params.resample_spacing_mm > 0) {
      out_geometry = resampled_geometry(g, params.resample_spacing_mm, params.keep_coarser_axes);
      check_image_size(out_geometry.size, limits_, what);
    }
    Frame frame(*ctx_, uint32_t(4 * slabs + 1));
    Buffer& w = frame.temp_buffer(weights.size() * sizeof(float), kStorage, true, what);
    std::copy(weights.begin(), weights.end(), static_cast<float*>(w.mapped));
    Buffer* tmp[5];
    for (auto& t : tmp) t = &frame.temp_buffer(uint64_t(held) * slice_bytes, kStorage, false, what);
    Buffer &sx = *tmp[0], &dx = *tmp[1], &sxsy = *tmp[2], &sxdy = *tmp[3], &dxsy = *tmp[4];
    auto field = make_field_image(*ctx_, frame, n, what);
    // Workgroups of a pass along `axis` over `extent` voxels: one invocation per kFieldBlock
    // outputs along the axis.
    auto dispatch_pass = [&](int axis, Eigen::Vector3i extent) {
      extent[axis] = (extent[axis] + gpu::kFieldBlock - 1) / gpu::kFieldBlock;
      frame.cmd().dispatch(uint32_t((extent.x() + gpu::kVoxelGroup - 1) / gpu::kVoxelGroup), uint32_t(extent.y()),
                           uint32_t(extent.z()));
    };
    const Pipeline& pass = ctx_->pipeline(Shader::field_pass_buffer);
    const Eigen::Matrix3d m = g.direction * g.spacing.cwiseInverse().asDiagonal();
    for (int z0 = 0; z0 < n.z(); z0 += slab) {
      const int z1 = std::min(n.z(), z0 + slab);
      const int in0 = std::max(0, z0 - rz), in1 = std::min(n.z(), z1 + rz);  // slices the slab reads
      const Eigen::Vector3i part(n.x(), n.y(), in1 - in0);
      // size.w of the x pass: the slab's first slice in the attenuation image.
      const gpu::ivec4 size{part.x(), part.y(), part.z(), in0};
      // x: mu -> Sx, Dx
      gpu::FilterPush fp{size, 0, f[0].radius, offset[0], 3};
      frame.bind(ctx_->pipeline(Shader::field_pass_image),
                 {Binding::sampled(mu.image(), ctx_->linear_sampler()), Binding::storage(w), Binding::storage(sx),
                  Binding::storage(dx)},
                 &fp, sizeof(fp));
      dispatch_pass(0, part);
      frame.mark("x pass");
      frame.barrier();
      // y: Sx -> SxSy, SxDy; Dx -> DxSy
      fp = {size, 1, f[1].radius, offset[1], 3};
      frame.bind(pass, {Binding::storage(sx), Binding::storage(w), Binding::storage(sxsy), Binding::storage(sxdy)}, &fp,
                 sizeof(fp));
      dispatch_pass(1, part);
      fp.flags = 1;
      frame.bind(pass, {Binding::storage(dx), Binding::storage(w), Binding::storage(dxsy), Binding::storage(dxsy)}, &fp,
                 sizeof(fp));
      dispatch_pass(1, part);
      frame.mark("y passes");
      frame.barrier();
      // z over the slab's output slices, fused with grad = D S^-1 d_index
      const gpu::FinalPush final_push{{n.x(), n.y(), n.z(), in0}, vec4_of(m.col(0)), vec4_of(m.col(1)), vec4_of(m.col(2)),
                                      rz, offset[2], z0, z1 - z0};
      frame.bind(ctx_->pipeline(Shader::field_final),
                 {Binding::storage(dxsy), Binding::storage(sxdy), Binding::storage(sxsy), Binding::storage(w),
                  Binding::storage_image(field)},
                 &final_push, sizeof(final_push));
      dispatch_pass(2, Eigen::Vector3i(n.x(), n.y(), z1 - z0));
      frame.mark("z pass and matrix");
      frame.barrier();  // the next slab overwrites the intermediates
    }
    if (params.resample_spacing_mm > 0) {
      const Eigen::Vector3i dn = out_geometry.size;
      auto resampled = make_field_image(*ctx_, frame, dn, what);
      const Eigen::Vector3d scale = out_geometry.spacing.cwiseQuotient(g.spacing);
      const gpu::ResamplePush rp{{dn.x(), dn.y(), dn.z(), 0}, vec4_of(g.physical_to_index(out_geometry.origin)),
                                 vec4_of(scale), vec4_of(n.cast<double>().cwiseInverse())};
      frame.bind(ctx_->pipeline(Shader::resample, manual_trilinear()),
                 {Binding::sampled(field, ctx_->linear_sampler()), Binding::storage_image(resampled)}, &rp, sizeof(rp));
      frame.cmd().dispatch(uint32_t((dn.x() + gpu::kVoxelGroup - 1) / gpu::kVoxelGroup), uint32_t(dn.y()),
                           uint32_t(dn.z()));
      frame.mark("resample");
      frame.run(what);
      return std::make_shared<VulkanVolume>(out_geometry, 3, this, ctx_, std::move(resampled));
    }
    frame.run(what);
    return std::make_shared<VulkanVolume>(g, 3, this, ctx_, std::move(field));
  }

  // Unless the limits say (tests), trilinear reads go by hand where the device cannot filter the
  // formats linearly, or where its filter is coarser than the ops' tolerances
  // (tests/backend_equivalence_test.cpp: 1e-4 of the largest value; measured on the first op that
  // reads trilinearly, once per device).
  bool manual_trilinear() const {
    if (limits_.manual_trilinear) return *limits_.manual_trilinear;
    return !ctx_->info().linear_filtering() || ctx_->linear_filter_error() > kExactFilterError;
  }

  std::shared_ptr<Context> ctx_;
  Limits limits_;
};

int parse_device_index(std::string_view option) {
  if (option.empty()) return 0;
  int index = -1;
  const auto [end, ec] = std::from_chars(option.data(), option.data() + option.size(), index);
  if (ec != std::errc() || end != option.data() + option.size() || index < 0)
    throw InputError("--backend vulkan:" + std::string(option) + ": expected a device index after ':' (see `fluoro devices`)");
  return index;
}

}  // namespace

std::unique_ptr<Backend> make_vulkan_backend_from_option(std::string_view option) {
  return make_vulkan_backend(parse_device_index(option));
}

std::unique_ptr<Backend> make_vulkan_backend(int index, const std::optional<Limits>& limits, bool shared_context) {
  return guarded("vulkan", [&] { return std::unique_ptr<Backend>(new VulkanBackend(index, limits, shared_context)); });
}

}  // namespace fluoro::vulkan
