#include "kernels/vulkan/vulkan_volume.hpp"

#include <cstring>

#include "engine/error.hpp"

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
std::unique_ptr<Image3D> upload(Context& ctx, const Eigen::Vector3i& size, vk::Format format, vk::ImageUsageFlags usage,
                                size_t bytes, const std::function<void(void*)>& fill, std::string_view what) {
  check_image_size(size, ctx.limits(), what);
  Frame frame(ctx, 0);
  Buffer& staging = frame.temp_buffer(bytes, vk::BufferUsageFlagBits::eTransferSrc, true, what);
  fill(staging.mapped);
  auto im = ctx.make_image(extent_of(size), format, usage | vk::ImageUsageFlagBits::eTransferDst, what);
  to_general(frame, *im);
  frame.cmd().copyBufferToImage(*staging.buffer, *im->image, vk::ImageLayout::eGeneral, whole(*im));
  frame.run(what);
  return im;
}

constexpr auto kFieldUsage = vk::ImageUsageFlagBits::eStorage | vk::ImageUsageFlagBits::eSampled |
                             vk::ImageUsageFlagBits::eTransferSrc | vk::ImageUsageFlagBits::eTransferDst;

}  // namespace

void check_image_size(const Eigen::Vector3i& n, const Limits& limits, std::string_view what) {
  if (n.maxCoeff() > int64_t(limits.max_image_dimension_3d))
    throw InputError(std::string(what) + ": a " + std::to_string(n.x()) + " x " + std::to_string(n.y()) + " x " +
                     std::to_string(n.z()) + " volume exceeds the device's largest 3D image (" +
                     std::to_string(limits.max_image_dimension_3d) +
                     " voxels per side); crop or resample it, or use the cpu backend");
}

std::unique_ptr<Image3D> make_field_image(Context& ctx, Frame& frame, const Eigen::Vector3i& size, std::string_view what) {
  check_image_size(size, ctx.limits(), what);
  auto im = ctx.make_image(extent_of(size), vk::Format::eR32G32B32A32Sfloat, kFieldUsage, what);
  to_general(frame, *im);
  return im;
}

std::unique_ptr<Image3D> upload_scalar(Context& ctx, const Volume& mu, std::string_view what) {
  return upload(ctx, mu.geometry.size, vk::Format::eR32Sfloat,
                vk::ImageUsageFlagBits::eSampled | vk::ImageUsageFlagBits::eTransferSrc, mu.voxels.size() * sizeof(float),
                [&](void* dst) { std::memcpy(dst, mu.voxels.data(), mu.voxels.size() * sizeof(float)); }, what);
}

std::unique_ptr<Image3D> upload_field(Context& ctx, const VectorField& f, std::string_view what) {
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

std::vector<std::array<float, 3>> download_field(Context& ctx, const Image3D& im, std::string_view what) {
  const size_t n = size_t(im.extent.width) * im.extent.height * im.extent.depth;
  Frame frame(ctx, 0);
  Buffer& staging = frame.temp_buffer(n * 4 * sizeof(float), vk::BufferUsageFlagBits::eTransferDst, true, what);
  frame.cmd().copyImageToBuffer(*im.image, vk::ImageLayout::eGeneral, *staging.buffer, whole(im));
  frame.run(what);
  std::vector<std::array<float, 3>> out(n);
  const float* s = static_cast<const float*>(staging.mapped);
  for (size_t i = 0; i < n; ++i) out[i] = {s[4 * i], s[4 * i + 1], s[4 * i + 2]};
  return out;
}

}  // namespace fluoro::vulkan
