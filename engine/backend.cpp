#include "engine/backend.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
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
    case Op::gradient_floor: return "gradient_floor";
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

void Backend::require(Op op) const {
  if (!supports(op))
    throw BackendUnavailable(std::string(name()) + ": " + std::string(op_name(op)) +
                             " is not supported on this device (see `fluoro devices`)");
}

PixelWindow Backend::resolve_window(const PixelWindow& w, const PinholeCamera& cam) {
  if (w.width == 0 || w.height == 0) return {0, 0, cam.width, cam.height};
  if (w.x0 < 0 || w.y0 < 0 || w.width < 0 || w.height < 0 || int64_t(w.x0) + w.width > cam.width ||
      int64_t(w.y0) + w.height > cam.height)
    throw InputError("pixel window " + std::to_string(w.width) + "x" + std::to_string(w.height) +
                     "+" + std::to_string(w.x0) + "+" + std::to_string(w.y0) +
                     " leaves the " + std::to_string(cam.width) + "x" +
                     std::to_string(cam.height) + " image");
  return w;
}

namespace {

// Rays are marched in steps of at most this many samples; a smaller step would mean millions of
// samples per ray (or an int overflow), never a useful DRR.
constexpr double kMinStepMm = 1e-3;

void check_step(double step_mm, std::string_view op) {
  if (!std::isfinite(step_mm) || step_mm < kMinStepMm)
    throw InputError(std::string(op) + ": step " + std::to_string(step_mm) + " mm is not a finite value of at least " +
                     std::to_string(kMinStepMm) + " mm");
}

void check_pixels(const std::vector<Eigen::Vector2f>& pixels, std::string_view op, size_t view) {
  for (const auto& p : pixels)
    if (!p.allFinite())
      throw InputError(std::string(op) + ": view " + std::to_string(view) + " has a non-finite pixel coordinate");
}

void check_views(std::span<const PinholeCamera> views, size_t per_view, std::string_view what, std::string_view op) {
  if (per_view != views.size())
    throw InputError(std::string(op) + ": " + std::to_string(per_view) + " " + std::string(what) + " for " +
                     std::to_string(views.size()) + " views");
  for (size_t v = 0; v < views.size(); ++v) validate_camera(views[v], std::string(op) + ": view " + std::to_string(v));
}

}  // namespace

std::shared_ptr<const DeviceVolume> Backend::upload(const Volume& mu) {
  validate_geometry(mu.geometry, std::string(name()) + ".upload");
  if (mu.voxels.size() != mu.geometry.voxel_count())
    throw InputError(std::string(name()) + ".upload: " + std::to_string(mu.voxels.size()) +
                     " voxels for a geometry of " + std::to_string(mu.geometry.voxel_count()));
  return upload_impl(mu);  // the backend checks finiteness in its own pass over the data
}

std::shared_ptr<const DeviceVolume> Backend::upload(const VectorField& f) {
  validate_geometry(f.geometry, std::string(name()) + ".upload");
  if (f.vectors.size() != f.geometry.voxel_count())
    throw InputError(std::string(name()) + ".upload: " + std::to_string(f.vectors.size()) +
                     " vectors for a geometry of " + std::to_string(f.geometry.voxel_count()));
  return upload_impl(f);
}

VectorField Backend::download_gradient(const DeviceVolume& g) {
  check_handle(g, 3, "download_gradient");
  return download_gradient_impl(g);
}

std::vector<uint8_t> Backend::save_volume(const DeviceVolume& v) {
  if (v.owner() != this) throw std::invalid_argument("save_volume: a volume from another backend");
  return save_volume_impl(v);
}

std::shared_ptr<const DeviceVolume> Backend::load_volume(const VolumeGeometry& geometry, int components,
                                                         std::span<const uint8_t> bytes, const std::string& what) {
  validate_geometry(geometry, what);
  if (components != 1 && components != 3) throw InputError(what + ": volumes have 1 or 3 components, not " + std::to_string(components));
  return load_volume_impl(geometry, components, bytes, what);
}

std::vector<uint8_t> Backend::save_volume_impl(const DeviceVolume&) {
  throw BackendUnavailable("the " + std::string(name()) + " backend cannot save its volumes (prepared files are made with --backend cpu)");
}

std::shared_ptr<const DeviceVolume> Backend::load_volume_impl(const VolumeGeometry&, int, std::span<const uint8_t>,
                                                              const std::string& what) {
  throw BackendUnavailable(what + ": the " + std::string(name()) + " backend cannot load saved volumes (use --backend cpu)");
}

std::shared_ptr<const DeviceVolume> Backend::floor_gradient(const DeviceVolume& gradient, const GradientFloorParams& params) {
  require(Op::gradient_floor);
  check_handle(gradient, 3, "gradient_floor");
  if (!std::isfinite(params.relative_tolerance) || params.relative_tolerance < 0 || params.relative_tolerance >= 1)
    throw InputError("gradient_floor: relative tolerance " + std::to_string(params.relative_tolerance) +
                     " must be at least 0 and below 1");
  return floor_gradient_impl(gradient, params);
}

std::shared_ptr<const DeviceVolume> Backend::floor_gradient_impl(const DeviceVolume& gradient,
                                                                 const GradientFloorParams& params) {
  VectorField f = download_gradient_impl(gradient);
  double max_squared = 0;
  for (const auto& v : f.vectors)
    max_squared = std::max(max_squared, double(v[0]) * v[0] + double(v[1]) * v[1] + double(v[2]) * v[2]);
  const double floor_squared = max_squared * params.relative_tolerance * params.relative_tolerance;
  for (auto& v : f.vectors)
    if (double(v[0]) * v[0] + double(v[1]) * v[1] + double(v[2]) * v[2] < floor_squared) v = {0.0f, 0.0f, 0.0f};
  return upload_impl(f);
}

std::shared_ptr<const DeviceVolume> Backend::gradient_field(const DeviceVolume& mu, const GradientFieldParams& params) {
  require(Op::gradient_field);
  check_handle(mu, 1, "gradient_field");
  if (!std::isfinite(params.sigma_mm) || params.sigma_mm < 0)
    throw InputError("gradient_field: sigma " + std::to_string(params.sigma_mm) + " mm must be a non-negative number");
  if (!std::isfinite(params.resample_spacing_mm) || params.resample_spacing_mm < 0)
    throw InputError("gradient_field: resample spacing must be a non-negative number");
  if (params.resample_spacing_mm > 0) {
    // The resampled grid must stay a sane size (the cpu backend indexes voxels with 32 bits).
    double voxels = 1;
    for (int a = 0; a < 3; ++a) {
      const double spacing = params.keep_coarser_axes ? std::max(params.resample_spacing_mm, mu.geometry().spacing[a])
                                                      : params.resample_spacing_mm;
      voxels *= std::ceil(mu.geometry().size[a] * mu.geometry().spacing[a] / spacing);
    }
    if (voxels > 1.5e9)
      throw InputError("gradient_field: resampling to " + std::to_string(params.resample_spacing_mm) + " mm gives " +
                       std::to_string(voxels) + " voxels, more than 1.5e9");
  }
  return gradient_field_impl(mu, params);
}

std::vector<Image> Backend::drr(const DeviceVolume& mu, std::span<const Pose> poses,
                                std::span<const PinholeCamera> views, const DrrParams& params) {
  require(Op::drr);
  check_handle(mu, 1, "drr");
  check_step(params.step_mm, "drr");
  check_views(views, views.size(), "views", "drr");
  for (const auto& v : views) resolve_window(params.window, v);
  return drr_impl(mu, poses, views, params);
}

std::vector<std::vector<Eigen::Vector2f>> Backend::gradient_projection(
    const DeviceVolume& g, std::span<const Pose> poses, std::span<const PinholeCamera> views,
    std::span<const std::vector<Eigen::Vector2f>> pixels, const ProjectionParams& params) {
  require(Op::gradient_projection);
  check_handle(g, 3, "gradient_projection");
  check_step(params.step_mm, "gradient_projection");
  check_views(views, pixels.size(), "pixel lists", "gradient_projection");
  for (size_t v = 0; v < pixels.size(); ++v) check_pixels(pixels[v], "gradient_projection", v);
  return gradient_projection_impl(g, poses, views, pixels, params);
}

std::vector<double> Backend::gpr_score(const DeviceVolume& g, std::span<const Pose> poses,
                                       std::span<const PinholeCamera> views, std::span<const EdgePixels> edges,
                                       const GprParams& params) {
  require(Op::gpr_score);
  check_handle(g, 3, "gpr_score");
  check_step(params.projection.step_mm, "gpr_score");
  check_views(views, edges.size(), "edge pixel sets", "gpr_score");
  for (size_t v = 0; v < edges.size(); ++v) {
    if (edges[v].directions.size() != edges[v].pixels.size())
      throw InputError("gpr_score: view " + std::to_string(v) + " has " + std::to_string(edges[v].pixels.size()) +
                       " edge pixels but " + std::to_string(edges[v].directions.size()) + " directions");
    check_pixels(edges[v].pixels, "gpr_score", v);
    check_pixels(edges[v].directions, "gpr_score", v);
  }
  if (!std::isfinite(params.max_angle_deg)) throw InputError("gpr_score: max_angle_deg is not finite");
  return gpr_score_impl(g, poses, views, edges, params);
}

}  // namespace fluoro
