#include "kernels/vulkan/vulkan_volume.hpp"

#include <algorithm>
#include <cstring>

#include "engine/error.hpp"
#include "kernels/vulkan/gpu_params.hpp"

namespace fluoro::vulkan {
namespace {

vk::Extent3D extent_of(const Eigen::Vector3i& n) { return {uint32_t(n.x()), uint32_t(n.y()), uint32_t(n.z())}; }

void to_general(Frame& frame, const Image3D& im) {
  const vk::ImageMemoryBarrier b{.srcAccessMask = {},
                                 .dstAccessMask = vk::AccessFlagBits::eTransferWrite | vk::AccessFlagBits::eShaderWrite |
                                                  vk::AccessFlagBits::eShaderRead,
                                 .oldLayout = vk::ImageLayout::eUndefined,
                                 .newLayout = vk::ImageLayout::eGeneral,
                                 .srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
                                 .dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
                                 .image = *im.image,
                                 .subresourceRange = {vk::ImageAspectFlagBits::eColor, 0, 1, 0, 1}};
  frame.cmd().pipelineBarrier(vk::PipelineStageFlagBits::eTopOfPipe,
                              vk::PipelineStageFlagBits::eTransfer | vk::PipelineStageFlagBits::eComputeShader, {}, {},
                              {}, b);
}

vk::BufferImageCopy whole(const Image3D& im) {
  return vk::BufferImageCopy{.bufferOffset = 0,
                             .bufferRowLength = 0,
                             .bufferImageHeight = 0,
                             .imageSubresource = {vk::ImageAspectFlagBits::eColor, 0, 0, 1},
                             .imageOffset = {0, 0, 0},
                             .imageExtent = im.extent};
}

// Staging buffer -> new image (GENERAL layout), one submission.
std::shared_ptr<Image3D> upload(Context& ctx, const Eigen::Vector3i& size, vk::Format format, vk::ImageUsageFlags usage,
                                size_t bytes, const std::function<void(void*)>& fill, std::string_view what) {
  check_image_size(size, ctx.limits(), what);
  Frame frame(ctx, 0);
  Buffer& staging = frame.temp_buffer(bytes, vk::BufferUsageFlagBits::eTransferSrc, true, what);
  fill(staging.mapped);
  auto im = ctx.make_image(extent_of(size), format, usage | vk::ImageUsageFlagBits::eTransferDst, what);
  frame.keep(im);
  to_general(frame, *im);
  frame.cmd().copyBufferToImage(*staging.buffer, *im->image, vk::ImageLayout::eGeneral, whole(*im));
  frame.run(what);
  return im;
}

constexpr auto kFieldUsage = vk::ImageUsageFlagBits::eStorage | vk::ImageUsageFlagBits::eSampled |
                             vk::ImageUsageFlagBits::eTransferSrc | vk::ImageUsageFlagBits::eTransferDst;

}  // namespace

std::vector<uint8_t> brick_distances(const std::vector<uint32_t>& flags, const Eigen::Vector3i& nb) {
  const int nx = nb.x(), ny = nb.y(), nz = nb.z();
  auto at = [&](int x, int y, int z) { return (size_t(z) * size_t(ny) + size_t(y)) * size_t(nx) + size_t(x); };
  const int cap = kMaxBrickDistance;
  // Distances along x to the nearest brick with data within one brick (the dilation) of the line...
  std::vector<int> d(flags.size(), cap), e(flags.size(), cap);
  for (int z = 0; z < nz; ++z)
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x < nx; ++x) {
        bool near = false;  // any flag in the 3 x 3 x 3 neighbourhood: the one-brick dilation
        for (int c = std::max(0, z - 1); c <= std::min(nz - 1, z + 1) && !near; ++c)
          for (int b = std::max(0, y - 1); b <= std::min(ny - 1, y + 1) && !near; ++b)
            for (int a = std::max(0, x - 1); a <= std::min(nx - 1, x + 1) && !near; ++a) near = flags[at(a, b, c)] != 0;
        if (near) d[at(x, y, z)] = 0;
      }
  // ... then the separable Chebyshev transform: h(p) = min_q max(|p - q|, g(q)) along x, y, z.
  auto pass = [&](const std::vector<int>& g, std::vector<int>& h, int axis) {
    const int n = nb[axis];
    for (int z = 0; z < nz; ++z)
      for (int y = 0; y < ny; ++y)
        for (int x = 0; x < nx; ++x) {
          const int p[3] = {x, y, z};
          int best = cap;
          for (int a = 0; a < best; ++a)  // outwards: |o| = a can only improve on best while a < best
            for (const int o : {-a, a}) {
              if (p[axis] + o < 0 || p[axis] + o >= n) continue;
              int q[3] = {x, y, z};
              q[axis] += o;
              best = std::min(best, std::max(a, g[at(q[0], q[1], q[2])]));
            }
          h[at(x, y, z)] = best;
        }
  };
  pass(d, e, 0);
  pass(e, d, 1);
  pass(d, e, 2);
  std::vector<uint8_t> out(flags.size());
  for (size_t i = 0; i < out.size(); ++i) out[i] = uint8_t(e[i]);
  return out;
}

VulkanVolume::VulkanVolume(const VolumeGeometry& g, int components, const void* owner, std::shared_ptr<Context> ctx,
                           std::shared_ptr<Image3D> image)
    : DeviceVolume(g, components, owner), ctx_(std::move(ctx)), image_(std::move(image)) {
  const Eigen::Vector3i n = g.size;
  const Eigen::Vector3i nb = (n.array() + (kBrick - 1)) / kBrick;
  const size_t count = size_t(nb.x()) * size_t(nb.y()) * size_t(nb.z());
  std::vector<uint32_t> flags(count);
  {
    Frame frame(*ctx_, 1);
    Buffer& out = frame.temp_buffer(count * sizeof(uint32_t), vk::BufferUsageFlagBits::eStorageBuffer, true, "vulkan.occupancy");
    const gpu::BrickPush push{{n.x(), n.y(), n.z(), components}, {nb.x(), nb.y(), nb.z(), 0}};
    frame.bind(ctx_->pipeline(Shader::brick_occupancy),
               {Binding::sampled(image_, ctx_->nearest_sampler()), Binding::storage(out)}, &push, sizeof(push));
    frame.cmd().dispatch(uint32_t((nb.x() + 63) / 64), uint32_t(nb.y()), uint32_t(nb.z()));
    frame.run("vulkan.occupancy");
    std::memcpy(flags.data(), out.mapped, count * sizeof(uint32_t));
  }
  const std::vector<uint8_t> distances = brick_distances(flags, nb);
  distance_map_ = upload(*ctx_, nb, vk::Format::eR8Uint, vk::ImageUsageFlagBits::eSampled, count,
                         [&](void* dst) { std::memcpy(dst, distances.data(), count); }, "vulkan.occupancy");
}

void check_image_size(const Eigen::Vector3i& n, const Limits& limits, std::string_view what) {
  if (n.maxCoeff() > int64_t(limits.max_image_dimension_3d))
    throw InputError(std::string(what) + ": a " + std::to_string(n.x()) + " x " + std::to_string(n.y()) + " x " +
                     std::to_string(n.z()) + " volume exceeds the device's largest 3D image (" +
                     std::to_string(limits.max_image_dimension_3d) +
                     " voxels per side); crop or resample it, or use the cpu backend");
}

std::shared_ptr<Image3D> make_field_image(Context& ctx, Frame& frame, const Eigen::Vector3i& size, std::string_view what) {
  check_image_size(size, ctx.limits(), what);
  auto im = ctx.make_image(extent_of(size), vk::Format::eR32G32B32A32Sfloat, kFieldUsage, what);
  frame.keep(im);
  to_general(frame, *im);
  return im;
}

std::shared_ptr<Image3D> upload_scalar(Context& ctx, const Volume& mu, std::string_view what) {
  return upload(ctx, mu.geometry.size, vk::Format::eR32Sfloat,
                vk::ImageUsageFlagBits::eSampled | vk::ImageUsageFlagBits::eTransferSrc, mu.voxels.size() * sizeof(float),
                [&](void* dst) { std::memcpy(dst, mu.voxels.data(), mu.voxels.size() * sizeof(float)); }, what);
}

std::shared_ptr<Image3D> upload_field(Context& ctx, const VectorField& f, std::string_view what) {
  return upload(ctx, f.geometry.size, vk::Format::eR32G32B32A32Sfloat, kFieldUsage, f.vectors.size() * 4 * sizeof(float),
                [&](void* dst) {
                  float* d = static_cast<float*>(dst);
                  for (size_t i = 0; i < f.vectors.size(); ++i) {
                    d[4 * i] = f.vectors[i][0];
                    d[4 * i + 1] = f.vectors[i][1];
                    d[4 * i + 2] = f.vectors[i][2];
                    d[4 * i + 3] = 0.0f;
                  }
                },
                what);
}

VectorBuffer download_field(Context& ctx, const std::shared_ptr<Image3D>& image,
                                                 std::string_view what) {
  const Image3D& im = *image;
  const size_t n = size_t(im.extent.width) * im.extent.height * im.extent.depth;
  Frame frame(ctx, 0);
  frame.keep(image);
  Buffer& staging = frame.temp_buffer(n * 4 * sizeof(float), vk::BufferUsageFlagBits::eTransferDst, true, what);
  frame.cmd().copyImageToBuffer(*im.image, vk::ImageLayout::eGeneral, *staging.buffer, whole(im));
  frame.run(what);
  VectorBuffer out(n);
  const float* s = static_cast<const float*>(staging.mapped);
  for (size_t i = 0; i < n; ++i) out[i] = {s[4 * i], s[4 * i + 1], s[4 * i + 2]};
  return out;
}

}  // namespace fluoro::vulkan
