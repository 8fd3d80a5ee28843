#pragma once
// The vulkan backend: every op as compute shaders (shaders/), on the device a name like
// "vulkan:1" picks ("vulkan" is device 0). Named "vulkan" in the registry wherever it is built.
#include <memory>
#include <optional>
#include <string_view>

#include "engine/backend.hpp"
#include "kernels/vulkan/vulkan_context.hpp"

namespace fluoro::vulkan {

// The backend on device `index`. `limits`, when given, replace the device's own (tests use lower
// ones to reach the refusals without gigabytes of data). shared_context = false gives the backend
// a device context of its own instead of the process-wide one (benchmarks of cold set-up: device
// creation and the driver's shader compilation). Throws BackendUnavailable without a usable
// device, InputError for an index past the last device.
std::unique_ptr<Backend> make_vulkan_backend(int index, const std::optional<Limits>& limits = std::nullopt,
                                             bool shared_context = true);
// The registry's factory (kernels/backend_registry.hpp): "" is device 0, "1" device 1.
std::unique_ptr<Backend> make_vulkan_backend_from_option(std::string_view option);

}  // namespace fluoro::vulkan
