#include "engine/backend.hpp"

#include <map>
#include <stdexcept>

#include "engine/error.hpp"

namespace fluoro {

std::string_view op_name(Op op) {
  switch (op) {
    case Op::gradient_field: return "gradient_field";
    case Op::drr: return "drr";
    case Op::gradient_projection: return "gradient_projection";
    case Op::gpr_score: return "gpr_score";
  }
  return "unknown";
}

void Backend::check_handle(const DeviceVolume& v, int components, std::string_view op) const {
  if (v.owner() != this)
    throw std::invalid_argument(std::string(name()) + "." + std::string(op) +
                                ": volume handle belongs to another backend");
  if (v.components() != components)
    throw std::invalid_argument(std::string(name()) + "." + std::string(op) + ": expected a " +
                                std::to_string(components) + "-component volume");
}

PixelWindow Backend::resolve_window(const PixelWindow& w, const PinholeCamera& cam) {
  if (w.width == 0 || w.height == 0) return {0, 0, cam.width, cam.height};
  if (w.x0 < 0 || w.y0 < 0 || w.width < 0 || w.height < 0 || w.x0 + w.width > cam.width ||
      w.y0 + w.height > cam.height)
    throw InputError("pixel window " + std::to_string(w.width) + "x" + std::to_string(w.height) +
                     "+" + std::to_string(w.x0) + "+" + std::to_string(w.y0) +
                     " leaves the " + std::to_string(cam.width) + "x" +
                     std::to_string(cam.height) + " image");
  return w;
}

namespace {
std::map<std::string, BackendFactory, std::less<>>& registry() {
  static std::map<std::string, BackendFactory, std::less<>> r;
  return r;
}
}  // namespace

bool register_backend(std::string_view name, BackendFactory factory) {
  registry()[std::string(name)] = factory;
  return true;
}

std::vector<std::string> backend_names() {
  std::vector<std::string> names;
  for (const auto& [n, f] : registry()) names.push_back(n);
  return names;
}

std::unique_ptr<Backend> make_backend(std::string_view name) {
  const auto it = registry().find(name);
  if (it == registry().end()) {
    std::string known;
    for (const auto& n : backend_names()) known += (known.empty() ? "" : ", ") + n;
    throw InputError("--backend " + std::string(name) + ": unknown backend (available: " + known + ")");
  }
  return it->second();
}

}  // namespace fluoro
