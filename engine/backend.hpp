#pragma once
// The backend interface: every compute op of the engine, batched over poses and views. Pipelines
// talk only to this interface. Data lives on the backend (upload once, use many times) behind
// opaque DeviceVolume handles; results come back as host types.
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "engine/camera.hpp"
#include "engine/image.hpp"
#include "engine/ops.hpp"
#include "engine/pose.hpp"
#include "engine/volume.hpp"

namespace fluoro {

// A scalar volume (1 component) or a gradient field (3 components) resident on a backend. Only
// the backend that made it can read it.
class DeviceVolume {
 public:
  DeviceVolume(VolumeGeometry geometry, int components, const void* owner)
      : geometry_(std::move(geometry)), components_(components), owner_(owner) {}
  virtual ~DeviceVolume() = default;
  DeviceVolume(const DeviceVolume&) = delete;
  DeviceVolume& operator=(const DeviceVolume&) = delete;

  const VolumeGeometry& geometry() const { return geometry_; }
  int components() const { return components_; }
  const void* owner() const { return owner_; }

 private:
  VolumeGeometry geometry_;
  int components_;
  const void* owner_;
};

class Backend {
 public:
  virtual ~Backend() = default;
  virtual std::string_view name() const = 0;
  virtual bool supports(Op op) const = 0;

  // Attenuation volume (mu per mm) to the backend.
  virtual std::shared_ptr<const DeviceVolume> upload(const Volume& mu) = 0;
  // A gradient field from elsewhere (say, a file or another backend) to the backend.
  virtual std::shared_ptr<const DeviceVolume> upload(const VectorField& gradient) = 0;
  virtual VectorField download_gradient(const DeviceVolume& gradient) = 0;

  // Op::gradient_field: the gradient of mu in the CT physical frame (1/mm^2).
  virtual std::shared_ptr<const DeviceVolume> gradient_field(const DeviceVolume& mu,
                                                             const GradientFieldParams& params) = 0;

  // Op::drr: one image per (pose, view), pose-major: result[p * views.size() + v], each the size
  // of params.window (or the view's whole image).
  virtual std::vector<Image> drr(const DeviceVolume& mu, std::span<const Pose> poses,
                                 std::span<const PinholeCamera> views, const DrrParams& params) = 0;

  // Op::gradient_projection: for each (pose, view) the expected image gradient (d DRR / du,
  // d DRR / dv, per pixel) at pixels[v]; result[p * views.size() + v][i].
  virtual std::vector<std::vector<Eigen::Vector2f>> gradient_projection(
      const DeviceVolume& gradient, std::span<const Pose> poses,
      std::span<const PinholeCamera> views, std::span<const std::vector<Eigen::Vector2f>> pixels,
      const ProjectionParams& params) = 0;

  // Op::gpr_score: per pose, the sum over views and edge pixels of |expected gradient|, a pixel
  // counting zero when its expected gradient deviates from edges[v].directions[i] by more than
  // params.max_angle_deg.
  virtual std::vector<double> gpr_score(const DeviceVolume& gradient, std::span<const Pose> poses,
                                        std::span<const PinholeCamera> views,
                                        std::span<const EdgePixels> edges,
                                        const GprParams& params) = 0;

 protected:
  // Throws std::invalid_argument when a handle from another backend, or one with the wrong number
  // of components, is passed in: a programming error, not bad input.
  void check_handle(const DeviceVolume& v, int components, std::string_view op) const;
  // The view's whole image when window is empty; throws InputError when it leaves the image.
  static PixelWindow resolve_window(const PixelWindow& window, const PinholeCamera& cam);
};

// Backends by name: "reference", "cpu" (and "vulkan" where built). Throws InputError listing the
// available names for an unknown one.
std::unique_ptr<Backend> make_backend(std::string_view name);
std::vector<std::string> backend_names();

// Registration hook for backend implementations (kernels/*), called at static-init time.
using BackendFactory = std::unique_ptr<Backend> (*)();
bool register_backend(std::string_view name, BackendFactory factory);

}  // namespace fluoro
