// fluoro devices: the backends this build offers and the Vulkan devices the vulkan backend can
// run on, with the limits that matter to it.
#include <cstdio>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "engine/backend.hpp"
#include "engine/error.hpp"
#include "engine/thread_limit.hpp"
#include "kernels/cpu/simd_targets.hpp"

#if FLUORO_HAVE_VULKAN
#include "kernels/backend_registry.hpp"
#include "kernels/vulkan/vulkan_context.hpp"
#endif

namespace fluoro::cli {
namespace {

std::string mib(uint64_t bytes) {
  char buf[32];
  if (bytes >= (uint64_t(1) << 30)) std::snprintf(buf, sizeof buf, "%.1f GiB", double(bytes) / double(1 << 30));
  else std::snprintf(buf, sizeof buf, "%llu MiB", static_cast<unsigned long long>(bytes >> 20));
  return buf;
}

void run() {
  std::string names;
  for (const auto& n : backend_names()) names += (names.empty() ? "" : ", ") + n;
  std::printf("backends: %s\n", names.c_str());
  // The limit as oneTBB applies it: --threads N shows here as N (docs/cli.md).
  std::printf("threads: at most %d per parallel loop\n", thread_limit());
  std::string simd;
  for (const auto& n : cpu::simd_targets()) simd += (simd.empty() ? "" : ", ") + n;
  std::printf("cpu SIMD: %s (--simd NAME caps it; this build and CPU offer %s)\n", cpu::simd_target().c_str(), simd.c_str());
#if FLUORO_HAVE_VULKAN
  std::vector<vulkan::DeviceInfo> devices;
  try {
    devices = vulkan::list_devices();
  } catch (const BackendUnavailable& e) {
    std::printf("vulkan devices: none (%s)\n", e.what());
    return;
  }
  if (devices.empty()) {
    std::printf("vulkan devices: none (the Vulkan loader found no device)\n");
    return;
  }
  std::printf("vulkan devices (--backend vulkan:N; plain vulkan is device 0):\n");
  for (const auto& d : devices) {
    std::printf("  %d: %s [%s], Vulkan %s\n", d.index, d.name.c_str(), d.type.c_str(), d.api_version.c_str());
    std::printf("     max 3D image %u^3, max storage buffer %s, max allocation %s, device-local memory %s\n",
                d.limits.max_image_dimension_3d, mib(d.limits.max_storage_buffer_range).c_str(),
                mib(d.limits.max_allocation).c_str(), mib(d.device_local_bytes).c_str());
    std::printf("     max workgroups per dispatch %u, subgroup size %u, sub-texel precision %u bits (claimed; the backend\n"
                "     measures its filter and reads by hand where it is not exact)\n",
                d.limits.max_group_count_x, d.subgroup_size, d.sub_texel_precision_bits);
    std::string ops;
    for (const Op op : kAllOps)
      if (d.supports(op)) ops += (ops.empty() ? "" : ", ") + std::string(op_name(op));
    std::printf("     compute queue %s, float 3D linear filtering %s, ops: %s\n", d.compute_queue ? "yes" : "no",
                d.linear_filtering() ? "yes" : "no (every trilinear read by hand)",
                d.usable() ? ops.c_str() : "none (not usable by the vulkan backend)");
  }
#else
  std::printf("vulkan devices: this build has no vulkan backend (Vulkan headers or glslangValidator were missing)\n");
#endif
}

}  // namespace

void add_devices_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("devices", "List the backends and the Vulkan devices with their limits");
  cmd->callback([] { run(); });
}

}  // namespace fluoro::cli
