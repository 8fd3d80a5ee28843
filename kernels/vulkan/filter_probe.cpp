// The sampler's linear filter, measured rather than taken from subTexelPrecisionBits (lavapipe
// claims 8 bits and interpolates in float). A 2x2x2 field whose components are each voxel's own
// index (i, j, k) is resampled by shaders/resample.comp at 64 positions along x, past both faces,
// with fractions that are no multiple of a power of two; the exact answer is the clamped position.
#include <algorithm>
#include <cmath>

#include "kernels/vulkan/gpu_params.hpp"
#include "kernels/vulkan/vulkan_context.hpp"
#include "kernels/vulkan/vulkan_volume.hpp"

namespace fluoro::vulkan {

double measure_linear_filter_error(Context& ctx, bool manual_trilinear) {
  constexpr const char* what = "vulkan: linear filter probe";
  VectorField ramp;
  ramp.geometry.size = Eigen::Vector3i(2, 2, 2);
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 2; ++i) ramp.vectors.push_back({float(i), float(j), float(k)});
  const auto src = upload_field(ctx, ramp, what);
  constexpr int kSamples = 64;
  const gpu::vec4 offset{-0.6137f, 0.3719f, 0.6581f, 0.0f}, scale{0.0371f, 0.0f, 0.0f, 0.0f};
  Frame frame(ctx, 1);
  const auto dst = make_field_image(ctx, frame, Eigen::Vector3i(kSamples, 1, 1), what);
  const gpu::ResamplePush push{{kSamples, 1, 1, 0}, offset, scale, {0.5f, 0.5f, 0.5f, 0.0f}};
  frame.bind(ctx.pipeline(Shader::resample, manual_trilinear),
             {Binding::sampled(src, ctx.linear_sampler()), Binding::storage_image(dst)}, &push, sizeof(push));
  frame.cmd().dispatch(uint32_t((kSamples + gpu::kVoxelGroup - 1) / gpu::kVoxelGroup), 1, 1);
  frame.run(what);
  const VectorBuffer got = download_field(ctx, dst, what);
  double error = 0;
  for (int p = 0; p < kSamples; ++p) {
    const double x = std::clamp(double(offset.x) + double(scale.x) * p, 0.0, 1.0);
    error = std::max({error, std::abs(got[size_t(p)][0] - x), std::abs(got[size_t(p)][1] - double(offset.y)),
                      std::abs(got[size_t(p)][2] - double(offset.z))});
  }
  return error;
}

double Context::linear_filter_error() {
  std::call_once(filter_probe_once_, [&] { linear_filter_error_ = measure_linear_filter_error(*this, false); });
  return linear_filter_error_;
}

}  // namespace fluoro::vulkan
