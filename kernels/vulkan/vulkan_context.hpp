#pragma once
// The Vulkan device the backend runs on: instance, physical-device choice, one compute queue,
// memory allocation helpers, the per-shader pipeline cache, and one-shot submissions that wait on
// a fence with a time limit (an error instead of a hang). Contexts are shared per device index
// by every backend object in the process (device creation and shader compilation are done once).
#define VULKAN_HPP_NO_CONSTRUCTORS  // designated initialisers for the Vulkan structs
#include <vulkan/vulkan_raii.hpp>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "engine/ops.hpp"

namespace fluoro::vulkan {

// The device limits the backend honours (from the device; tests may lower them).
struct Limits {
  uint32_t max_image_dimension_3d = 0;
  uint64_t max_storage_buffer_range = 0;  // bytes one storage-buffer binding may cover
  uint64_t max_allocation = 0;            // bytes of one memory allocation
  uint32_t max_group_count_x = 0;         // workgroups along x of one dispatch
  uint32_t max_group_count_yz = 0;        // along y and z
  uint64_t storage_offset_alignment = 1;  // minStorageBufferOffsetAlignment
  // Trilinear reads by hand (eight texelFetch, float weights) instead of the sampler's linear
  // filter: for devices whose filter weights are too coarse for the ops' tolerances (most GPUs
  // use 8-bit sub-texel weights: errors up to 1/512 of a voxel-to-voxel difference). The backend
  // measures the filter (linear_filter_error) unless this is set; tests set it to exercise the
  // by-hand path.
  std::optional<bool> manual_trilinear;
};

// What `fluoro devices` prints about each device.
struct DeviceInfo {
  int index = 0;
  std::string name, type, api_version, driver;
  Limits limits;
  uint64_t device_local_bytes = 0;
  // The image formats' features the ops need (optimal tiling, 3D): CT volumes are R32_SFLOAT
  // sampled images, gradient fields R32G32B32A32_SFLOAT sampled (and storage, to compute them
  // here), the empty-space distance maps R8_UINT sampled. Linear filtering is optional: without
  // it every trilinear read is done by hand (Limits::manual_trilinear).
  bool volume_sampled = false, field_sampled = false, field_storage = false, distance_map_sampled = false;
  bool volume_linear_filter = false, field_linear_filter = false;
  bool compute_queue = false;
  uint32_t subgroup_size = 0;  // SIMD width of the device's compute invocations (informational)
  // The filter-weight precision the device claims (VkPhysicalDeviceLimits); lavapipe claims 8 bits
  // but interpolates in float, so the backend measures instead of trusting it.
  uint32_t sub_texel_precision_bits = 0;
  // Whether the vulkan backend can run on it (at least the DRR), and each op on it.
  bool usable() const { return compute_queue && volume_sampled && distance_map_sampled; }
  bool supports(Op op) const;
  // Both formats filter linearly; otherwise every trilinear read is done by hand.
  bool linear_filtering() const { return volume_linear_filter && field_linear_filter; }
};

// Every Vulkan device the loader finds, in its order. Throws BackendUnavailable when there is no
// Vulkan loader or driver at all.
std::vector<DeviceInfo> list_devices();

struct Buffer {
  vk::raii::Buffer buffer = nullptr;
  vk::raii::DeviceMemory memory = nullptr;
  void* mapped = nullptr;  // host-visible buffers only (persistently mapped, coherent)
  vk::DeviceSize size = 0;
  vk::BufferUsageFlags usage;
  bool host_visible = false;
};

struct Image3D {
  vk::raii::Image image = nullptr;
  vk::raii::DeviceMemory memory = nullptr;
  vk::raii::ImageView view = nullptr;
  vk::Format format = vk::Format::eUndefined;
  vk::Extent3D extent;
};

enum class Shader {
  drr,
  projection_trilinear,
  projection_nearest,
  score_trilinear,
  score_nearest,
  field_pass_image,
  field_pass_buffer,
  field_final,
  resample,
  brick_occupancy,
};

struct Pipeline {
  std::vector<vk::DescriptorType> bindings;  // binding i has type bindings[i]
  uint32_t push_size = 0;
  vk::raii::DescriptorSetLayout set_layout = nullptr;
  vk::raii::PipelineLayout layout = nullptr;
  vk::raii::Pipeline pipeline = nullptr;
};

// One descriptor of a set, in binding order. Images are held by shared pointers: the frame that
// binds one keeps it alive until its submission is done (or for ever, after a timeout).
struct Binding {
  vk::DescriptorType type;
  vk::Buffer buffer = nullptr;
  vk::DeviceSize offset = 0, range = 0;
  vk::ImageView view = nullptr;
  vk::Sampler sampler = nullptr;
  std::shared_ptr<const Image3D> image;
  // Storage buffers: a frame's own temporaries (the frame owns them).
  static Binding storage(const Buffer& b, vk::DeviceSize offset = 0, vk::DeviceSize range = VK_WHOLE_SIZE) {
    return {vk::DescriptorType::eStorageBuffer, *b.buffer, offset, range, nullptr, nullptr, nullptr};
  }
  static Binding sampled(const std::shared_ptr<const Image3D>& i, vk::Sampler s) {
    return {vk::DescriptorType::eCombinedImageSampler, nullptr, 0, 0, *i->view, s, i};
  }
  static Binding storage_image(const std::shared_ptr<const Image3D>& i) {
    return {vk::DescriptorType::eStorageImage, nullptr, 0, 0, *i->view, nullptr, i};
  }
};

class Context;

// The resources of one submission: a command buffer being recorded, its descriptor sets, the
// temporary buffers its commands use, shared ownership of the images and the device context they
// use, and its fence. run() submits and waits; after a timeout the frame and everything it holds
// are leaked, never freed under a device that may still be using them.
class Frame {
 public:
  Frame(Context& ctx, uint32_t max_sets);
  Frame(Frame&&) = default;
  // Gives the temporary buffers back to the context's pool (a frame leaked after a timeout never
  // gets here: its buffers stay with it).
  ~Frame();
  // Keeps an image used by a recorded command (other than through a Binding) alive with the frame.
  void keep(std::shared_ptr<const Image3D> image) { images_.push_back(std::move(image)); }
  const vk::raii::CommandBuffer& cmd() const { return cmd_; }
  // A descriptor set for `p` with these bindings (one per binding of the shader, in order).
  vk::DescriptorSet make_set(const Pipeline& p, const std::vector<Binding>& bindings);
  // Binds p with a fresh set and push constants.
  void bind(const Pipeline& p, const std::vector<Binding>& bindings, const void* push, uint32_t push_size);
  // A buffer that lives until the frame is done (taken from the context's pool when one fits).
  Buffer& temp_buffer(vk::DeviceSize size, vk::BufferUsageFlags usage, bool host_visible, std::string_view what);
  // compute shader writes -> compute shader / transfer / host reads.
  void barrier();
  // With FLUORO_VULKAN_PROFILE set, a device timestamp: run() prints the device time between
  // consecutive marks (where a submission's time goes). No-op otherwise.
  void mark(const char* label);
  // Ends, submits and waits (throws std::runtime_error on a timeout or a lost device).
  void run(std::string_view what);

 private:
  std::shared_ptr<Context> owner_;  // destroyed last
  Context& ctx_;
  std::chrono::steady_clock::time_point created_ = std::chrono::steady_clock::now();
  std::vector<std::shared_ptr<const Image3D>> images_;
  std::vector<std::unique_ptr<Buffer>> buffers_;
  vk::raii::CommandPool pool_ = nullptr;
  vk::raii::CommandBuffer cmd_ = nullptr;
  vk::raii::DescriptorPool descriptor_pool_ = nullptr;
  std::vector<vk::raii::DescriptorSet> sets_;
  vk::raii::Fence fence_ = nullptr;
  vk::raii::QueryPool timestamps_ = nullptr;
  std::vector<const char*> marks_;
};

class Context : public std::enable_shared_from_this<Context> {
 public:
  // The context of device `index` (shared, created on first use). Throws BackendUnavailable when
  // there is no Vulkan device, InputError for an index past the last device.
  static std::shared_ptr<Context> get(int index);

  const vk::raii::Device& device() const { return device_; }
  const vk::raii::Queue& queue() const { return queue_; }
  uint32_t queue_family() const { return queue_family_; }
  const DeviceInfo& info() const { return info_; }
  double timestamp_period_ns() const { return timestamp_period_ns_; }
  const Limits& limits() const { return info_.limits; }
  vk::Sampler linear_sampler() const { return *linear_sampler_; }
  vk::Sampler nearest_sampler() const { return *nearest_sampler_; }  // for integer formats

  std::unique_ptr<Buffer> make_buffer(vk::DeviceSize size, vk::BufferUsageFlags usage, bool host_visible,
                                      std::string_view what);
  std::shared_ptr<Image3D> make_image(const vk::Extent3D& extent, vk::Format format, vk::ImageUsageFlags usage,
                                      std::string_view what);
  // Frames' temporary buffers come from a pool of those earlier frames gave back: allocating
  // device memory for every op call costs time on real drivers, whose count of live allocations
  // is also limited (maxMemoryAllocationCount, 4096 on many). A pooled buffer is reused when it
  // has the same usage and memory kind and at most twice the size asked for rounded up to a power
  // of two; new ones are rounded up so, so that batches of varying size reuse them. The pool keeps at
  // most kBufferPoolBytes, the least recently returned buffers leaving first.
  static constexpr vk::DeviceSize kBufferPoolBytes = 256ull << 20;
  std::unique_ptr<Buffer> take_buffer(vk::DeviceSize size, vk::BufferUsageFlags usage, bool host_visible,
                                      std::string_view what);
  void give_back(std::unique_ptr<Buffer> buffer);
  // Buffers allocated so far (made, not taken from the pool): for tests.
  size_t buffers_allocated() const { return buffers_allocated_; }
  // The pipeline of a shader, compiled on first use; manual_trilinear specialises the
  // trilinear reads (shaders/common/sampling.glsl) to the by-hand path.
  const Pipeline& pipeline(Shader s, bool manual_trilinear = false);
  // The largest error of the sampler's linear filter, in units of the difference between two
  // neighbouring voxels, measured once on this device (filter_probe.cpp): about 1e-7 for a filter
  // that interpolates in float, up to 2e-3 with 8-bit weights.
  double linear_filter_error();

  // Submissions from several threads take turns.
  std::mutex& submit_mutex() { return submit_mutex_; }
  // After a timed-out submission the device is not trusted again.
  void mark_broken(std::string why) { broken_ = std::move(why); }
  void check_usable(std::string_view what) const;
  double fence_timeout_s() const { return fence_timeout_s_; }
  // FLUORO_VULKAN_PROFILE set: every submission prints its host and device times to stderr.
  bool profile() const { return profile_; }

  Context(int index);  // use get()

 private:
  uint32_t memory_type(uint32_t type_bits, vk::MemoryPropertyFlags required, vk::MemoryPropertyFlags preferred,
                       std::string_view what) const;

  vk::raii::Context context_;
  vk::raii::Instance instance_ = nullptr;
  vk::raii::PhysicalDevice physical_ = nullptr;
  vk::raii::Device device_ = nullptr;
  vk::raii::Queue queue_ = nullptr;
  uint32_t queue_family_ = 0;
  DeviceInfo info_;
  vk::PhysicalDeviceMemoryProperties memory_;
  vk::raii::Sampler linear_sampler_ = nullptr, nearest_sampler_ = nullptr;
  vk::raii::PipelineCache pipeline_cache_ = nullptr;
  std::mutex pipelines_mutex_, submit_mutex_;
  std::map<std::pair<Shader, bool>, std::unique_ptr<Pipeline>> pipelines_;
  std::mutex pool_mutex_;
  std::vector<std::unique_ptr<Buffer>> pool_;  // oldest first
  vk::DeviceSize pooled_bytes_ = 0;
  std::atomic<size_t> buffers_allocated_{0};
  std::once_flag filter_probe_once_;
  double linear_filter_error_ = 0;
  std::string broken_;
  double fence_timeout_s_ = 300;
  bool profile_ = false;
  double timestamp_period_ns_ = 0;  // 0: no timestamps on the compute queue
};

// The error of trilinear reads on this device (see Context::linear_filter_error), through the
// sampler's filter or, with manual_trilinear, by hand (filter_probe.cpp).
double measure_linear_filter_error(Context& ctx, bool manual_trilinear);

// Runs f, turning Vulkan errors into one-line errors naming the op: out of memory and device
// loss become std::runtime_error ("vulkan.drr: out of device memory ..."), as does any other
// vk::SystemError. InputError passes through.
template <class F>
auto guarded(std::string_view what, F&& f) -> decltype(f());
[[noreturn]] void rethrow_vulkan_error(std::string_view what);

template <class F>
auto guarded(std::string_view what, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const vk::SystemError&) {
    rethrow_vulkan_error(what);
  }
}

}  // namespace fluoro::vulkan
