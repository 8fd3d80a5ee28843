#include "kernels/vulkan/vulkan_context.hpp"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

#include "engine/backend.hpp"
#include "engine/error.hpp"

namespace fluoro::vulkan {
namespace {

std::string type_name(vk::PhysicalDeviceType t) {
  switch (t) {
    case vk::PhysicalDeviceType::eIntegratedGpu: return "integrated GPU";
    case vk::PhysicalDeviceType::eDiscreteGpu: return "discrete GPU";
    case vk::PhysicalDeviceType::eVirtualGpu: return "virtual GPU";
    case vk::PhysicalDeviceType::eCpu: return "CPU";
    default: return "other";
  }
}

std::string version_string(uint32_t v) {
  return std::to_string(VK_API_VERSION_MAJOR(v)) + "." + std::to_string(VK_API_VERSION_MINOR(v)) + "." +
         std::to_string(VK_API_VERSION_PATCH(v));
}

constexpr const char* kNoDevice =
    "vulkan: no Vulkan device found (looked for a Vulkan loader, libvulkan.so.1, and an installed driver "
    "(ICD) with a compute queue; on Debian `apt install mesa-vulkan-drivers` gives the lavapipe CPU driver)";

// The loader and an instance (Vulkan 1.1: the shaders' SPIR-V target).
vk::raii::Instance make_instance(const vk::raii::Context& context) {
  const vk::ApplicationInfo app{.pApplicationName = "fluoro", .applicationVersion = 1, .pEngineName = "fluoro",
                                .engineVersion = 1, .apiVersion = VK_API_VERSION_1_1};
  return vk::raii::Instance(context, vk::InstanceCreateInfo{.pApplicationInfo = &app});
}

DeviceInfo describe(const vk::raii::PhysicalDevice& pd, int index) {
  const auto chain = pd.getProperties2<vk::PhysicalDeviceProperties2, vk::PhysicalDeviceMaintenance3Properties,
                                       vk::PhysicalDeviceSubgroupProperties>();
  const auto& p = chain.get<vk::PhysicalDeviceProperties2>().properties;
  DeviceInfo d;
  d.index = index;
  d.name = p.deviceName.data();
  d.type = type_name(p.deviceType);
  d.api_version = version_string(p.apiVersion);
  d.driver = std::to_string(p.driverVersion);
  d.limits.max_image_dimension_3d = p.limits.maxImageDimension3D;
  d.limits.max_storage_buffer_range = p.limits.maxStorageBufferRange;
  d.limits.max_allocation = chain.get<vk::PhysicalDeviceMaintenance3Properties>().maxMemoryAllocationSize;
  d.limits.max_group_count_x = p.limits.maxComputeWorkGroupCount[0];
  d.limits.max_group_count_yz = std::min(p.limits.maxComputeWorkGroupCount[1], p.limits.maxComputeWorkGroupCount[2]);
  d.limits.storage_offset_alignment = std::max<uint64_t>(1, p.limits.minStorageBufferOffsetAlignment);
  d.sub_texel_precision_bits = p.limits.subTexelPrecisionBits;
  const auto mem = pd.getMemoryProperties();
  for (uint32_t h = 0; h < mem.memoryHeapCount; ++h)
    if (mem.memoryHeaps[h].flags & vk::MemoryHeapFlagBits::eDeviceLocal) d.device_local_bytes += mem.memoryHeaps[h].size;
  using F = vk::FormatFeatureFlagBits;
  const auto volume = pd.getFormatProperties(vk::Format::eR32Sfloat).optimalTilingFeatures;
  const auto field = pd.getFormatProperties(vk::Format::eR32G32B32A32Sfloat).optimalTilingFeatures;
  const auto distance = pd.getFormatProperties(vk::Format::eR8Uint).optimalTilingFeatures;
  d.volume_sampled = bool(volume & F::eSampledImage);
  d.volume_linear_filter = bool(volume & F::eSampledImageFilterLinear);
  d.field_sampled = bool(field & F::eSampledImage);
  d.field_linear_filter = bool(field & F::eSampledImageFilterLinear);
  d.field_storage = bool(field & F::eStorageImage);
  d.distance_map_sampled = bool(distance & F::eSampledImage);
  const auto& sg = chain.get<vk::PhysicalDeviceSubgroupProperties>();
  d.subgroup_size = sg.subgroupSize;
  for (const auto& q : pd.getQueueFamilyProperties())
    if (q.queueFlags & vk::QueueFlagBits::eCompute) d.compute_queue = true;
  return d;
}

}  // namespace

bool DeviceInfo::supports(Op op) const {
  if (!usable()) return false;
  switch (op) {
    case Op::drr:
      return true;
    case Op::gradient_projection:
    case Op::gpr_score:
      return field_sampled;
    case Op::gradient_field:
      return field_sampled && field_storage;
    case Op::gradient_floor:  // on the host (Backend's default): download, floor, upload
      return field_sampled;
  }
  return false;
}

void rethrow_vulkan_error(std::string_view what) {
  try {
    throw;
  } catch (const vk::OutOfDeviceMemoryError&) {
    throw std::runtime_error(std::string(what) + ": out of device memory (the volume or batch is too large for this device)");
  } catch (const vk::OutOfHostMemoryError&) {
    throw std::runtime_error(std::string(what) + ": out of host memory");
  } catch (const vk::DeviceLostError&) {
    throw std::runtime_error(std::string(what) + ": the Vulkan device was lost (driver crash or reset)");
  } catch (const vk::SystemError& e) {
    throw std::runtime_error(std::string(what) + ": Vulkan error: " + e.what());
  }
}

std::vector<DeviceInfo> list_devices() {
  try {
    vk::raii::Context context;
    const vk::raii::Instance instance = make_instance(context);
    std::vector<DeviceInfo> out;
    int i = 0;
    for (const auto& pd : vk::raii::PhysicalDevices(instance)) out.push_back(describe(pd, i++));
    return out;
  } catch (const vk::SystemError& e) {
    throw BackendUnavailable(std::string(kNoDevice) + ": " + e.what());
  } catch (const std::runtime_error& e) {  // vk::raii::Context: no loader
    throw BackendUnavailable(std::string(kNoDevice) + ": " + e.what());
  }
}

std::shared_ptr<Context> Context::get(int index) {
  // Deliberately never destroyed: tearing a driver down during static destruction races its own
  // teardown (and the loader's); the process exit releases everything.
  static auto* mutex = new std::mutex;
  static auto* contexts = new std::map<int, std::shared_ptr<Context>>;
  std::lock_guard lock(*mutex);
  auto& c = (*contexts)[index];
  if (!c) c = std::make_shared<Context>(index);
  return c;
}

Context::Context(int index) : context_([] {
  try {
    return vk::raii::Context();
  } catch (const std::runtime_error& e) {
    throw BackendUnavailable(std::string(kNoDevice) + ": " + e.what());
  }
}()) {
  std::vector<vk::raii::PhysicalDevice> devices;
  try {
    instance_ = make_instance(context_);
    devices = vk::raii::PhysicalDevices(instance_);
  } catch (const vk::SystemError& e) {
    throw BackendUnavailable(std::string(kNoDevice) + ": " + e.what());
  }
  if (devices.empty()) throw BackendUnavailable(kNoDevice);
  if (index < 0 || size_t(index) >= devices.size()) {
    std::string found;
    for (size_t i = 0; i < devices.size(); ++i)
      found += (i ? ", " : "") + std::to_string(i) + " " + std::string(devices[i].getProperties().deviceName.data());
    throw InputError("--backend vulkan:" + std::to_string(index) + ": no Vulkan device " + std::to_string(index) +
                     " (found " + std::to_string(devices.size()) + ": " + found + "; see `fluoro devices`)");
  }
  physical_ = std::move(devices[size_t(index)]);
  info_ = describe(physical_, index);
  memory_ = physical_.getMemoryProperties();
  if (!info_.usable())
    throw BackendUnavailable("vulkan:" + std::to_string(index) + " (" + info_.name +
                             "): the device has no compute queue or cannot sample 32-bit float and 8-bit integer 3D "
                             "images, which every op of the vulkan backend reads");

  const auto families = physical_.getQueueFamilyProperties();
  bool found = false;
  for (uint32_t f = 0; f < families.size() && !found; ++f)
    if (families[f].queueFlags & vk::QueueFlagBits::eCompute) {
      queue_family_ = f;
      found = true;
    }
  if (!found) throw BackendUnavailable("vulkan:" + std::to_string(index) + " (" + info_.name + "): no compute queue");
  const float priority = 1.0f;
  const vk::DeviceQueueCreateInfo q{.queueFamilyIndex = queue_family_, .queueCount = 1, .pQueuePriorities = &priority};
  device_ = vk::raii::Device(physical_, vk::DeviceCreateInfo{.queueCreateInfoCount = 1, .pQueueCreateInfos = &q});
  queue_ = vk::raii::Queue(device_, queue_family_, 0);
  const auto sampler = [&](vk::Filter filter) {
    return vk::raii::Sampler(device_, vk::SamplerCreateInfo{.magFilter = filter,
                                                            .minFilter = filter,
                                                            .mipmapMode = vk::SamplerMipmapMode::eNearest,
                                                            .addressModeU = vk::SamplerAddressMode::eClampToEdge,
                                                            .addressModeV = vk::SamplerAddressMode::eClampToEdge,
                                                            .addressModeW = vk::SamplerAddressMode::eClampToEdge,
                                                            .maxLod = 0.0f,
                                                            .unnormalizedCoordinates = VK_FALSE});
  };
  linear_sampler_ = sampler(vk::Filter::eLinear);
  nearest_sampler_ = sampler(vk::Filter::eNearest);
  pipeline_cache_ = vk::raii::PipelineCache(device_, vk::PipelineCacheCreateInfo{});
  if (const char* t = std::getenv("FLUORO_VULKAN_TIMEOUT_S"); t && std::atof(t) > 0) fence_timeout_s_ = std::atof(t);
  profile_ = std::getenv("FLUORO_VULKAN_PROFILE") != nullptr;
  if (families[queue_family_].timestampValidBits > 0)
    timestamp_period_ns_ = physical_.getProperties().limits.timestampPeriod;
}

void Context::check_usable(std::string_view what) const {
  if (!broken_.empty()) throw std::runtime_error(std::string(what) + ": the Vulkan device is unusable: " + broken_);
}

uint32_t Context::memory_type(uint32_t bits, vk::MemoryPropertyFlags required, vk::MemoryPropertyFlags preferred,
                              std::string_view what) const {
  int best = -1;
  for (uint32_t i = 0; i < memory_.memoryTypeCount; ++i) {
    const auto flags = memory_.memoryTypes[i].propertyFlags;
    if (!(bits & (1u << i)) || (flags & required) != required) continue;
    if ((flags & preferred) == preferred) return i;
    if (best < 0) best = int(i);
  }
  if (best < 0) throw std::runtime_error(std::string(what) + ": no suitable Vulkan memory type");
  return uint32_t(best);
}

std::unique_ptr<Buffer> Context::make_buffer(vk::DeviceSize size, vk::BufferUsageFlags usage, bool host_visible,
                                             std::string_view what) {
  if (size > limits().max_allocation)
    throw InputError(std::string(what) + ": " + std::to_string(size >> 20) + " MiB is more than the device's largest allocation (" +
                     std::to_string(limits().max_allocation >> 20) + " MiB)");
  auto b = std::make_unique<Buffer>();
  b->size = std::max<vk::DeviceSize>(size, 4);
  b->buffer = vk::raii::Buffer(device_, vk::BufferCreateInfo{.size = b->size, .usage = usage,
                                                             .sharingMode = vk::SharingMode::eExclusive});
  const auto req = b->buffer.getMemoryRequirements();
  const auto required = host_visible ? vk::MemoryPropertyFlagBits::eHostVisible | vk::MemoryPropertyFlagBits::eHostCoherent
                                     : vk::MemoryPropertyFlagBits::eDeviceLocal;
  const auto preferred = host_visible ? required | vk::MemoryPropertyFlagBits::eHostCached : required;
  b->memory = vk::raii::DeviceMemory(
      device_, vk::MemoryAllocateInfo{.allocationSize = req.size,
                                      .memoryTypeIndex = memory_type(req.memoryTypeBits, required, preferred, what)});
  b->buffer.bindMemory(*b->memory, 0);
  if (host_visible) b->mapped = b->memory.mapMemory(0, VK_WHOLE_SIZE);
  b->usage = usage;
  b->host_visible = host_visible;
  ++buffers_allocated_;
  return b;
}

namespace {
// The power of two (at least 4 KiB) a new pooled buffer is rounded up to.
vk::DeviceSize rounded_size(vk::DeviceSize size) {
  vk::DeviceSize r = 4096;
  while (r < size) r *= 2;
  return r;
}
}  // namespace

std::unique_ptr<Buffer> Context::take_buffer(vk::DeviceSize size, vk::BufferUsageFlags usage, bool host_visible,
                                             std::string_view what) {
  {
    std::lock_guard lock(pool_mutex_);
    // A buffer bound whole must stay within the storage-buffer range when the request does.
    const vk::DeviceSize range = limits().max_storage_buffer_range;
    int best = -1;
    for (size_t i = 0; i < pool_.size(); ++i) {
      const Buffer& b = *pool_[i];
      if (b.usage == usage && b.host_visible == host_visible && b.size >= size &&
          b.size <= 2 * rounded_size(size) && (size > range || b.size <= range) &&
          (best < 0 || b.size < pool_[size_t(best)]->size))
        best = int(i);
    }
    if (best >= 0) {
      std::unique_ptr<Buffer> b = std::move(pool_[size_t(best)]);
      pool_.erase(pool_.begin() + best);
      pooled_bytes_ -= b->size;
      return b;
    }
  }
  const vk::DeviceSize rounded = rounded_size(size);
  // Only what the pool may keep is rounded: a larger buffer is never reused, so rounding it up
  // would only waste device memory.
  const bool round = rounded <= kBufferPoolBytes && rounded <= limits().max_allocation &&
                     rounded <= limits().max_storage_buffer_range;
  return make_buffer(round ? rounded : size, usage, host_visible, what);
}

void Context::give_back(std::unique_ptr<Buffer> buffer) {
  if (!buffer || buffer->size > kBufferPoolBytes) return;
  std::lock_guard lock(pool_mutex_);
  while (!pool_.empty() && pooled_bytes_ + buffer->size > kBufferPoolBytes) {
    pooled_bytes_ -= pool_.front()->size;
    pool_.erase(pool_.begin());
  }
  pooled_bytes_ += buffer->size;
  pool_.push_back(std::move(buffer));
}

std::shared_ptr<Image3D> Context::make_image(const vk::Extent3D& extent, vk::Format format, vk::ImageUsageFlags usage,
                                             std::string_view what) {
  auto im = std::make_shared<Image3D>();
  im->format = format;
  im->extent = extent;
  im->image = vk::raii::Image(device_, vk::ImageCreateInfo{.imageType = vk::ImageType::e3D,
                                                           .format = format,
                                                           .extent = extent,
                                                           .mipLevels = 1,
                                                           .arrayLayers = 1,
                                                           .samples = vk::SampleCountFlagBits::e1,
                                                           .tiling = vk::ImageTiling::eOptimal,
                                                           .usage = usage,
                                                           .sharingMode = vk::SharingMode::eExclusive,
                                                           .initialLayout = vk::ImageLayout::eUndefined});
  const auto req = im->image.getMemoryRequirements();
  if (req.size > limits().max_allocation)
    throw InputError(std::string(what) + ": a " + std::to_string(extent.width) + " x " + std::to_string(extent.height) +
                     " x " + std::to_string(extent.depth) + " image needs " + std::to_string(req.size >> 20) +
                     " MiB, more than the device's largest allocation (" + std::to_string(limits().max_allocation >> 20) +
                     " MiB)");
  im->memory = vk::raii::DeviceMemory(
      device_, vk::MemoryAllocateInfo{.allocationSize = req.size,
                                      .memoryTypeIndex = memory_type(req.memoryTypeBits, vk::MemoryPropertyFlagBits::eDeviceLocal,
                                                                     vk::MemoryPropertyFlagBits::eDeviceLocal, what)});
  im->image.bindMemory(*im->memory, 0);
  im->view = vk::raii::ImageView(
      device_, vk::ImageViewCreateInfo{.image = *im->image,
                                       .viewType = vk::ImageViewType::e3D,
                                       .format = format,
                                       .subresourceRange = {vk::ImageAspectFlagBits::eColor, 0, 1, 0, 1}});
  return im;
}

Frame::Frame(Context& ctx, uint32_t max_sets) : owner_(ctx.shared_from_this()), ctx_(ctx) {
  const auto& d = ctx.device();
  pool_ = vk::raii::CommandPool(d, vk::CommandPoolCreateInfo{.flags = vk::CommandPoolCreateFlagBits::eTransient,
                                                             .queueFamilyIndex = ctx.queue_family()});
  cmd_ = std::move(vk::raii::CommandBuffers(d, vk::CommandBufferAllocateInfo{.commandPool = *pool_,
                                                                             .level = vk::CommandBufferLevel::ePrimary,
                                                                             .commandBufferCount = 1})
                       .front());
  max_sets = std::max(1u, max_sets);
  const vk::DescriptorPoolSize sizes[] = {{vk::DescriptorType::eStorageBuffer, 6 * max_sets},
                                          {vk::DescriptorType::eCombinedImageSampler, 2 * max_sets},
                                          {vk::DescriptorType::eStorageImage, max_sets}};
  descriptor_pool_ = vk::raii::DescriptorPool(
      d, vk::DescriptorPoolCreateInfo{.flags = vk::DescriptorPoolCreateFlagBits::eFreeDescriptorSet,
                                      .maxSets = max_sets,
                                      .poolSizeCount = 3,
                                      .pPoolSizes = sizes});
  fence_ = vk::raii::Fence(d, vk::FenceCreateInfo{});
  cmd_.begin(vk::CommandBufferBeginInfo{.flags = vk::CommandBufferUsageFlagBits::eOneTimeSubmit});
  if (ctx.profile() && ctx.timestamp_period_ns() > 0) {
    timestamps_ = vk::raii::QueryPool(d, vk::QueryPoolCreateInfo{.queryType = vk::QueryType::eTimestamp, .queryCount = 64});
    cmd_.resetQueryPool(*timestamps_, 0, 64);
    mark("start");
  }
}

void Frame::mark(const char* label) {
  if (!*timestamps_ || marks_.size() >= 64) return;
  cmd_.writeTimestamp(vk::PipelineStageFlagBits::eBottomOfPipe, *timestamps_, uint32_t(marks_.size()));
  marks_.push_back(label);
}

vk::DescriptorSet Frame::make_set(const Pipeline& p, const std::vector<Binding>& bindings) {
  if (bindings.size() != p.bindings.size()) throw std::logic_error("vulkan: descriptor count mismatch");
  vk::raii::DescriptorSets sets(ctx_.device(), vk::DescriptorSetAllocateInfo{.descriptorPool = *descriptor_pool_,
                                                                             .descriptorSetCount = 1,
                                                                             .pSetLayouts = &*p.set_layout});
  sets_.push_back(std::move(sets.front()));
  const vk::DescriptorSet set = *sets_.back();
  std::vector<vk::DescriptorBufferInfo> buffers(bindings.size());
  std::vector<vk::DescriptorImageInfo> images(bindings.size());
  std::vector<vk::WriteDescriptorSet> writes;
  for (size_t i = 0; i < bindings.size(); ++i) {
    const Binding& b = bindings[i];
    if (b.type != p.bindings[i]) throw std::logic_error("vulkan: descriptor type mismatch");
    if (b.image) images_.push_back(b.image);
    vk::WriteDescriptorSet w{.dstSet = set, .dstBinding = uint32_t(i), .descriptorCount = 1, .descriptorType = b.type};
    if (b.type == vk::DescriptorType::eStorageBuffer) {
      buffers[i] = vk::DescriptorBufferInfo{.buffer = b.buffer, .offset = b.offset, .range = b.range};
      w.pBufferInfo = &buffers[i];
    } else {
      images[i] = vk::DescriptorImageInfo{.sampler = b.sampler, .imageView = b.view, .imageLayout = vk::ImageLayout::eGeneral};
      w.pImageInfo = &images[i];
    }
    writes.push_back(w);
  }
  ctx_.device().updateDescriptorSets(writes, {});
  return set;
}

void Frame::bind(const Pipeline& p, const std::vector<Binding>& bindings, const void* push, uint32_t push_size) {
  const vk::DescriptorSet set = make_set(p, bindings);
  cmd_.bindPipeline(vk::PipelineBindPoint::eCompute, *p.pipeline);
  cmd_.bindDescriptorSets(vk::PipelineBindPoint::eCompute, *p.layout, 0, set, {});
  if (push_size) cmd_.pushConstants<uint8_t>(*p.layout, vk::ShaderStageFlagBits::eCompute, 0,
                                             vk::ArrayProxy<const uint8_t>(push_size, static_cast<const uint8_t*>(push)));
}

Buffer& Frame::temp_buffer(vk::DeviceSize size, vk::BufferUsageFlags usage, bool host_visible, std::string_view what) {
  buffers_.push_back(ctx_.take_buffer(size, usage, host_visible, what));
  return *buffers_.back();
}

Frame::~Frame() {
  for (auto& b : buffers_) ctx_.give_back(std::move(b));
}

void Frame::barrier() {
  const vk::MemoryBarrier b{.srcAccessMask = vk::AccessFlagBits::eShaderWrite | vk::AccessFlagBits::eTransferWrite,
                            .dstAccessMask = vk::AccessFlagBits::eShaderRead | vk::AccessFlagBits::eTransferRead |
                                             vk::AccessFlagBits::eHostRead};
  cmd_.pipelineBarrier(vk::PipelineStageFlagBits::eComputeShader | vk::PipelineStageFlagBits::eTransfer,
                       vk::PipelineStageFlagBits::eComputeShader | vk::PipelineStageFlagBits::eTransfer |
                           vk::PipelineStageFlagBits::eHost,
                       {}, b, {}, {});
}

void Frame::run(std::string_view what) {
  barrier();  // results visible to the host
  mark("end");
  cmd_.end();
  std::lock_guard lock(ctx_.submit_mutex());
  ctx_.check_usable(what);
  const vk::CommandBuffer cb = *cmd_;
  const auto submitted = std::chrono::steady_clock::now();
  ctx_.queue().submit(vk::SubmitInfo{.commandBufferCount = 1, .pCommandBuffers = &cb}, *fence_);
  const auto timeout = uint64_t(ctx_.fence_timeout_s() * 1e9);
  const vk::Result r = ctx_.device().waitForFences(*fence_, VK_TRUE, timeout);
  if (r == vk::Result::eTimeout) {
    // The device may still use this frame's memory: keep it (leaked) rather than free it under
    // the device, and refuse further work on this device.
    ctx_.mark_broken(std::string(what) + " did not finish within " + std::to_string(int(ctx_.fence_timeout_s())) + " s");
    new Frame(std::move(*this));
    throw std::runtime_error(std::string(what) + ": the Vulkan device did not finish within " +
                             std::to_string(int(ctx_.fence_timeout_s())) +
                             " s (FLUORO_VULKAN_TIMEOUT_S); the device is not used again");
  }
  if (ctx_.profile()) {
    const auto done = std::chrono::steady_clock::now();
    std::fprintf(stderr, "%.*s: host set-up and recording %.2f ms, device %.2f ms\n", int(what.size()), what.data(),
                 std::chrono::duration<double, std::milli>(submitted - created_).count(),
                 std::chrono::duration<double, std::milli>(done - submitted).count());
    if (marks_.size() > 1) {
      const auto [result, stamps] =
          timestamps_.getResults<uint64_t>(0, uint32_t(marks_.size()), marks_.size() * sizeof(uint64_t), sizeof(uint64_t),
                                           vk::QueryResultFlagBits::e64 | vk::QueryResultFlagBits::eWait);
      for (size_t i = 1; i < marks_.size(); ++i)
        std::fprintf(stderr, "  %s: %.2f ms\n", marks_[i],
                     double(stamps[i] - stamps[i - 1]) * ctx_.timestamp_period_ns() * 1e-6);
    }
  }
}

}  // namespace fluoro::vulkan
