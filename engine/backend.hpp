#pragma once
// The backend interface: every compute op of the engine, batched over poses and views. Pipelines
// talk only to this interface. Data lives on the backend (upload once, use many times) behind
// opaque DeviceVolume handles; results come back as host types.
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "engine/camera.hpp"
#include "engine/error.hpp"
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

// The public ops validate their arguments once, for every backend (bad sizes, non-finite pixels,
// a step too small to march, handles from another backend), then call the backend's *_impl.
//
// Thread safety, which sweeps and the Python bindings rely on: every op may be called from several
// threads at once on one backend, with the same or different DeviceVolumes (a sweep's parallel
// runs share one backend and its uploaded CT and fields). DeviceVolumes are immutable once made
// and may be shared between threads; results are returned by value. The cpu and reference
// backends keep no state between calls; the vulkan backend guards its pipeline cache, buffer pool
// and queue submissions with mutexes, so concurrent calls are correct but their GPU work is
// serialised. A backend must outlive the DeviceVolumes it made. Implementations of *_impl must
// keep this contract (tests/backend_equivalence_test.cpp, ConcurrentCalls...).
class Backend {
 public:
  virtual ~Backend() = default;
  virtual std::string_view name() const = 0;
  // Whether this backend, on its device, can run `op`; the public op throws BackendUnavailable
  // when it cannot (ggml's supports_op: callers and tests ask first and skip or fall back).
  virtual bool supports(Op op) const = 0;
  // True when scoring a batch of a few poses costs about as much as scoring one (a GPU, whose
  // dispatch latency dominates small batches); false when the cost grows with the batch (a CPU).
  // Optimisers use it to choose between speculative and on-demand evaluation.
  virtual bool prefers_batches() const { return false; }

  // Attenuation volume (mu per mm) to the backend. Throws InputError for an invalid geometry, a
  // voxel count that disagrees with it, or non-finite voxels.
  std::shared_ptr<const DeviceVolume> upload(const Volume& mu);
  // A gradient field from elsewhere (say, a file or another backend) to the backend.
  std::shared_ptr<const DeviceVolume> upload(const VectorField& gradient);
  VectorField download_gradient(const DeviceVolume& gradient);

  // A resident volume (scalar or gradient field) in this backend's own form, for files that spare
  // its recomputation (`fluoro prepare`, docs/cli.md): load_volume of the same backend turns the
  // bytes back into a volume identical to `v`, bit for bit, without recomputing anything costly.
  // Backends that cannot throw BackendUnavailable (can_save_volumes() is false). load_volume
  // throws InputError naming `what` when the bytes do not fit the geometry and component count.
  virtual bool can_save_volumes() const { return false; }
  std::vector<uint8_t> save_volume(const DeviceVolume& v);
  std::shared_ptr<const DeviceVolume> load_volume(const VolumeGeometry& geometry, int components,
                                                  std::span<const uint8_t> bytes, const std::string& what);

  // Op::gradient_field: the gradient of mu in the CT physical frame (1/mm^2).
  std::shared_ptr<const DeviceVolume> gradient_field(const DeviceVolume& mu, const GradientFieldParams& params);

  // Op::gradient_floor (engine/ops.hpp): a new field, `gradient` with its voxels of magnitude below
  // params.relative_tolerance * (its largest voxel magnitude) set to zero. Throws InputError for a
  // tolerance outside [0, 1).
  std::shared_ptr<const DeviceVolume> floor_gradient(const DeviceVolume& gradient, const GradientFloorParams& params);

  // Op::drr: one image per (pose, view), pose-major: result[p * views.size() + v], each the size
  // of params.window (or the view's whole image).
  std::vector<Image> drr(const DeviceVolume& mu, std::span<const Pose> poses, std::span<const PinholeCamera> views,
                         const DrrParams& params);

  // Op::gradient_projection: for each (pose, view) the expected image gradient (d DRR / du,
  // d DRR / dv, per pixel) at pixels[v]; result[p * views.size() + v][i].
  std::vector<std::vector<Eigen::Vector2f>> gradient_projection(const DeviceVolume& gradient,
                                                                std::span<const Pose> poses,
                                                                std::span<const PinholeCamera> views,
                                                                std::span<const std::vector<Eigen::Vector2f>> pixels,
                                                                const ProjectionParams& params);

  // Op::gpr_score: per pose, the sum over views and edge pixels of |expected gradient|, a pixel
  // counting zero when its expected gradient deviates from edges[v].directions[i] by more than
  // params.max_angle_deg.
  std::vector<double> gpr_score(const DeviceVolume& gradient, std::span<const Pose> poses,
                                std::span<const PinholeCamera> views, std::span<const EdgePixels> edges,
                                const GprParams& params);

 protected:
  // Called with validated arguments; windows already resolved to the image.
  virtual std::shared_ptr<const DeviceVolume> upload_impl(const Volume& mu) = 0;
  virtual std::shared_ptr<const DeviceVolume> upload_impl(const VectorField& gradient) = 0;
  virtual VectorField download_gradient_impl(const DeviceVolume& gradient) = 0;
  // Only called when can_save_volumes(); the defaults throw BackendUnavailable.
  virtual std::vector<uint8_t> save_volume_impl(const DeviceVolume& v);
  virtual std::shared_ptr<const DeviceVolume> load_volume_impl(const VolumeGeometry& geometry, int components,
                                                               std::span<const uint8_t> bytes, const std::string& what);
  virtual std::shared_ptr<const DeviceVolume> gradient_field_impl(const DeviceVolume& mu,
                                                                  const GradientFieldParams& params) = 0;
  // The default goes through the host: download, zero the weak voxels, upload (what the vulkan
  // backend does: a one-off step of preparation).
  virtual std::shared_ptr<const DeviceVolume> floor_gradient_impl(const DeviceVolume& gradient,
                                                                  const GradientFloorParams& params);
  virtual std::vector<Image> drr_impl(const DeviceVolume& mu, std::span<const Pose> poses,
                                      std::span<const PinholeCamera> views, const DrrParams& params) = 0;
  virtual std::vector<std::vector<Eigen::Vector2f>> gradient_projection_impl(
      const DeviceVolume& gradient, std::span<const Pose> poses, std::span<const PinholeCamera> views,
      std::span<const std::vector<Eigen::Vector2f>> pixels, const ProjectionParams& params) = 0;
  virtual std::vector<double> gpr_score_impl(const DeviceVolume& gradient, std::span<const Pose> poses,
                                             std::span<const PinholeCamera> views, std::span<const EdgePixels> edges,
                                             const GprParams& params) = 0;

  // The view's whole image when window is empty; throws InputError when it leaves the image.
  static PixelWindow resolve_window(const PixelWindow& window, const PinholeCamera& cam);

 private:
  void require(Op op) const;  // throws BackendUnavailable unless supports(op)
  // Throws std::invalid_argument when a handle from another backend, or one with the wrong number
  // of components, is passed in: a programming error, not bad input.
  void check_handle(const DeviceVolume& v, int components, std::string_view op) const;
};

// Backends by name (make_backend("cpu"), ...): kernels/backend_registry.hpp.

// A backend that is built in but cannot run here (no device, no driver). Still bad input to the
// CLI (exit 2); tests skip on it.
class BackendUnavailable : public InputError {
 public:
  using InputError::InputError;
};

}  // namespace fluoro
