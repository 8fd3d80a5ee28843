// The compute pipelines: one per shader variant, built from the SPIR-V embedded at build time
// (shaders/CMakeLists.txt) on first use and cached in the device's context. lavapipe compiles
// SPIR-V to machine code when the pipeline is created (tens of milliseconds per shader), so the
// cache matters: every later call reuses the pipeline.
#include <cstdint>
#include <span>

#include "kernels/vulkan/gpu_params.hpp"
#include "kernels/vulkan/vulkan_context.hpp"
#include "shaders/brick_occupancy_spv.spv.h"
#include "shaders/drr_spv.spv.h"
#include "shaders/field_final_spv.spv.h"
#include "shaders/field_pass_buffer_spv.spv.h"
#include "shaders/field_pass_image_spv.spv.h"
#include "shaders/projection_nearest_spv.spv.h"
#include "shaders/projection_trilinear_spv.spv.h"
#include "shaders/resample_spv.spv.h"
#include "shaders/score_nearest_spv.spv.h"
#include "shaders/score_trilinear_spv.spv.h"

namespace fluoro::vulkan {
namespace {

using T = vk::DescriptorType;
constexpr T kBuf = T::eStorageBuffer, kTex = T::eCombinedImageSampler, kImg = T::eStorageImage;

struct ShaderSpec {
  std::span<const uint32_t> spirv;
  std::vector<vk::DescriptorType> bindings;
  uint32_t push_size;
};

ShaderSpec spec(Shader s) {
  switch (s) {
    case Shader::drr: return {drr_spv, {kTex, kTex, kBuf, kBuf}, sizeof(gpu::MarchPush)};
    case Shader::projection_trilinear:
      return {projection_trilinear_spv, {kTex, kTex, kBuf, kBuf, kBuf, kBuf}, sizeof(gpu::MarchPush)};
    case Shader::projection_nearest:
      return {projection_nearest_spv, {kTex, kTex, kBuf, kBuf, kBuf, kBuf}, sizeof(gpu::MarchPush)};
    case Shader::score_trilinear: return {score_trilinear_spv, {kTex, kTex, kBuf, kBuf, kBuf, kBuf}, sizeof(gpu::MarchPush)};
    case Shader::score_nearest: return {score_nearest_spv, {kTex, kTex, kBuf, kBuf, kBuf, kBuf}, sizeof(gpu::MarchPush)};
    case Shader::field_pass_image: return {field_pass_image_spv, {kTex, kBuf, kBuf, kBuf}, sizeof(gpu::FilterPush)};
    case Shader::field_pass_buffer: return {field_pass_buffer_spv, {kBuf, kBuf, kBuf, kBuf}, sizeof(gpu::FilterPush)};
    case Shader::field_final: return {field_final_spv, {kBuf, kBuf, kBuf, kBuf, kImg}, sizeof(gpu::FinalPush)};
    case Shader::resample: return {resample_spv, {kTex, kImg}, sizeof(gpu::ResamplePush)};
    case Shader::brick_occupancy: return {brick_occupancy_spv, {kTex, kBuf}, sizeof(gpu::BrickPush)};
  }
  throw std::logic_error("vulkan: unknown shader");
}

}  // namespace

const Pipeline& Context::pipeline(Shader s, bool manual_trilinear) {
  std::lock_guard lock(pipelines_mutex_);
  auto& p = pipelines_[{s, manual_trilinear}];
  if (p) return *p;
  const ShaderSpec sp = spec(s);
  auto pl = std::make_unique<Pipeline>();
  pl->bindings = sp.bindings;
  pl->push_size = sp.push_size;
  std::vector<vk::DescriptorSetLayoutBinding> b;
  for (uint32_t i = 0; i < sp.bindings.size(); ++i)
    b.push_back({.binding = i, .descriptorType = sp.bindings[i], .descriptorCount = 1,
                 .stageFlags = vk::ShaderStageFlagBits::eCompute});
  pl->set_layout = vk::raii::DescriptorSetLayout(
      device_, vk::DescriptorSetLayoutCreateInfo{.bindingCount = uint32_t(b.size()), .pBindings = b.data()});
  const vk::PushConstantRange push{.stageFlags = vk::ShaderStageFlagBits::eCompute, .offset = 0, .size = sp.push_size};
  pl->layout = vk::raii::PipelineLayout(device_, vk::PipelineLayoutCreateInfo{.setLayoutCount = 1,
                                                                              .pSetLayouts = &*pl->set_layout,
                                                                              .pushConstantRangeCount = 1,
                                                                              .pPushConstantRanges = &push});
  const vk::raii::ShaderModule module(
      device_, vk::ShaderModuleCreateInfo{.codeSize = sp.spirv.size_bytes(), .pCode = sp.spirv.data()});
  // Specialisation constant 0: MANUAL_TRILINEAR (shaders/common/sampling.glsl). Shaders that do
  // not declare it ignore it.
  const vk::Bool32 manual = manual_trilinear ? VK_TRUE : VK_FALSE;
  const vk::SpecializationMapEntry entry{.constantID = 0, .offset = 0, .size = sizeof(vk::Bool32)};
  const vk::SpecializationInfo specialisation{.mapEntryCount = 1, .pMapEntries = &entry, .dataSize = sizeof(manual),
                                              .pData = &manual};
  pl->pipeline = vk::raii::Pipeline(
      device_, pipeline_cache_,
      vk::ComputePipelineCreateInfo{.stage = {.stage = vk::ShaderStageFlagBits::eCompute,
                                              .module = *module,
                                              .pName = "main",
                                              .pSpecializationInfo = &specialisation},
                                    .layout = *pl->layout});
  p = std::move(pl);
  return *p;
}

}  // namespace fluoro::vulkan
