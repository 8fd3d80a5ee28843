#pragma once
// The vulkan backend's resident volumes: a 3D image per volume, sampled through the hardware's
// linear filter. Attenuation: R32_SFLOAT; gradient fields: R32G32B32A32_SFLOAT (w unused), also
// written as storage images by the gradient-field and resampling passes. Uploads go through a
// host-visible staging buffer, once per volume. Each volume also carries a distance map for
// empty-space skipping (shaders/common/skipping.glsl): an R8_UINT 3D image of one texel per brick.
#include <memory>

#include "engine/backend.hpp"
#include "kernels/vulkan/vulkan_context.hpp"

namespace fluoro::vulkan {

class VulkanVolume final : public DeviceVolume {
 public:
  // Computes the volume's distance map (a submission of its own).
  VulkanVolume(const VolumeGeometry& g, int components, const void* owner, std::shared_ptr<Context> ctx,
               std::shared_ptr<Image3D> image);
  const std::shared_ptr<Image3D>& image() const { return image_; }
  const std::shared_ptr<Image3D>& distance_map() const { return distance_map_; }

 private:
  std::shared_ptr<Context> ctx_;  // outlives the images
  std::shared_ptr<Image3D> image_, distance_map_;
};

// Bricks of kBrick^3 voxels (BRICK in shaders/common/skipping.glsl); distances are capped at
// kMaxBrickDistance (leaps of up to kBrick * (kMaxBrickDistance - 1) voxels).
inline constexpr int kBrickShift = 2;
inline constexpr int kBrick = 1 << kBrickShift;
inline constexpr int kMaxBrickDistance = 16;

// The distance map from per-brick data flags (i fastest): flags dilated by one brick (a sample's
// trilinear or nearest reads, and float rounding at brick faces, reach into the neighbours), then
// the Chebyshev distance in bricks to the nearest flagged brick, capped. Host side, exposed for tests.
std::vector<uint8_t> brick_distances(const std::vector<uint32_t>& flags, const Eigen::Vector3i& bricks);

// Throws InputError when a grid does not fit the device's 3D images.
void check_image_size(const Eigen::Vector3i& size, const Limits& limits, std::string_view what);

// A new image of the gradient-field format, usable as storage image, sampled image and copy
// source/destination; in GENERAL layout once `frame` has run.
std::shared_ptr<Image3D> make_field_image(Context& ctx, Frame& frame, const Eigen::Vector3i& size,
                                          std::string_view what);

// One-shot uploads and downloads (each its own submission).
std::shared_ptr<Image3D> upload_scalar(Context& ctx, const Volume& mu, std::string_view what);
std::shared_ptr<Image3D> upload_field(Context& ctx, const VectorField& f, std::string_view what);
VectorBuffer download_field(Context& ctx, const std::shared_ptr<Image3D>& image,
                                                 std::string_view what);

}  // namespace fluoro::vulkan
