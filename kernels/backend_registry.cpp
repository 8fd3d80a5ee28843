#include "kernels/backend_registry.hpp"

#include <map>
#include <mutex>

#include "kernels/cpu/cpu_backend.hpp"
#include "kernels/reference/reference_backend.hpp"
#if FLUORO_HAVE_VULKAN
#include "kernels/vulkan/vulkan_backend.hpp"
#endif

namespace fluoro {
namespace {

std::unique_ptr<Backend> reference_factory(std::string_view option) {
  no_backend_option("reference", option);
  return make_reference_backend();
}

std::unique_ptr<Backend> cpu_factory(std::string_view option) {
  no_backend_option("cpu", option);
  return cpu::make_cpu_backend();
}

struct Registry {
  std::mutex mutex;
  std::map<std::string, BackendFactory, std::less<>> factories{
      {"reference", &reference_factory},
      {"cpu", &cpu_factory},
#if FLUORO_HAVE_VULKAN
      {"vulkan", &vulkan::make_vulkan_backend_from_option},
#endif
  };
};

Registry& registry() {
  static Registry r;
  return r;
}

}  // namespace

void register_backend(std::string_view name, BackendFactory factory) {
  std::lock_guard lock(registry().mutex);
  registry().factories[std::string(name)] = factory;
}

std::vector<std::string> backend_names() {
  std::lock_guard lock(registry().mutex);
  std::vector<std::string> names;
  for (const auto& [n, f] : registry().factories) names.push_back(n);
  return names;
}

void no_backend_option(std::string_view name, std::string_view option) {
  if (!option.empty())
    throw InputError("--backend " + std::string(name) + ":" + std::string(option) + ": the " + std::string(name) +
                     " backend takes no option after ':'");
}

std::unique_ptr<Backend> make_backend(std::string_view name) {
  const size_t colon = name.find(':');
  const std::string_view base = name.substr(0, colon);
  const std::string_view option = colon == std::string_view::npos ? std::string_view() : name.substr(colon + 1);
  BackendFactory factory = nullptr;
  {
    std::lock_guard lock(registry().mutex);
    const auto it = registry().factories.find(base);
    if (it != registry().factories.end()) factory = it->second;
  }
  if (!factory) {
    std::string known;
    for (const auto& n : backend_names()) known += (known.empty() ? "" : ", ") + n;
    throw InputError("--backend " + std::string(name) + ": unknown backend (available: " + known + ")");
  }
  return factory(option);
}

}  // namespace fluoro
