// fluoro drr: render a DRR of a CT from a camera at a pose.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/global_options.hpp"
#include "apps/fluoro/physics_options.hpp"
#include "engine/attenuation.hpp"
#include "engine/backend.hpp"
#include "engine/error.hpp"
#include "engine/json_io.hpp"
#include "engine/spaced_image_writer.hpp"
#include "engine/volume_io.hpp"
#include "engine/xray.hpp"
#include "kernels/backend_registry.hpp"

namespace fluoro::cli {
namespace {

struct DrrOptions {
  std::string ct, camera, pose, out, backend = "cpu", window;
  double step_mm = 1.0;
  double mu_water = 0.02;
  double bone_threshold_hu = -1e30;
  XrayPhysics physics;  // off by default: the plain line integrals
};

PixelWindow parse_window(const std::string& s) {
  PixelWindow w;
  char c1 = 0, c2 = 0, c3 = 0;
  std::istringstream in(s);
  if (!(in >> w.x0 >> c1 >> w.y0 >> c2 >> w.width >> c3 >> w.height) || c1 != ',' || c2 != ',' || c3 != ',' ||
      !(in >> std::ws).eof() || w.width <= 0 || w.height <= 0)
    throw_input_error("--window " + s, "expected X0,Y0,WIDTH,HEIGHT with positive width and height");
  return w;
}

void run(const DrrOptions& o) {
  using clock = std::chrono::steady_clock;
  const auto t_start = clock::now();
  if (!(o.step_mm >= 1e-3) || !std::isfinite(o.step_mm)) throw_input_error("--step", "must be a number of at least 0.001 mm");
  if (!(o.mu_water > 0) || !std::isfinite(o.mu_water)) throw_input_error("--mu-water", "must be a positive number");
  if (std::isnan(o.bone_threshold_hu)) throw_input_error("--bone-threshold", "must be a number");
  check_physics_options(o.physics);
  const PinholeCamera camera = read_camera(o.camera);
  const Pose pose = o.pose.empty() ? Pose::Identity() : read_pose(o.pose);
  DrrParams params;
  params.step_mm = o.step_mm;
  if (!o.window.empty()) params.window = parse_window(o.window);
  auto backend = make_backend(o.backend);
  const Volume mu = hu_to_attenuation(read_volume(o.ct), {o.mu_water, o.bone_threshold_hu});
  const auto t_loaded = clock::now();
  const auto device_mu = backend->upload(mu);
  auto images = backend->drr(*device_mu, std::span(&pose, 1), std::span(&camera, 1), params);
  // The imaging physics turns the line integrals into what a C-arm's log image would read. With a
  // --window, the scatter and the scaling see only the window (render the whole detector for them).
  if (o.physics.any()) images[0] = simulate_xray_physics(images[0], o.physics);
  const auto t_rendered = clock::now();
  // .mha/.nrrd carry the detector's pixel pitch (1 mm, i.e. pixel units, when the camera file
  // does not give it) and, for a window, where its first pixel sits on the detector.
  const Eigen::Vector2d spacing = camera.pixel_spacing_mm.value_or(Eigen::Vector2d::Ones());
  const Eigen::Vector2d origin(spacing.x() * params.window.x0, spacing.y() * params.window.y0);
  const LogDomainMapping m = write_drr(images[0], o.out, spacing, origin);
  const auto t_written = clock::now();
  if (!quiet()) {
    auto sec = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };
    std::printf("wrote %s (%d x %d, backend %s): load %.3f s, render %.3f s, write %.3f s\n", o.out.c_str(),
                images[0].width, images[0].height, std::string(backend->name()).c_str(),
                sec(t_start, t_loaded), sec(t_loaded, t_rendered), sec(t_rendered, t_written));
    if (is_spaced_image_path(o.out))
      std::printf("  pixel spacing %.6g x %.6g mm%s\n", spacing.x(), spacing.y(),
                  camera.pixel_spacing_mm ? " (the camera's)" : " (the camera gives none: pixel units)");
    if (m.b > 0)
      std::printf("  png: intensity = %.6g - %.6g * line_integral (16-bit, log domain, bone dark)\n", m.a, m.b);
  }
}

}  // namespace

void add_drr_command(CLI::App& app) {
  auto o = std::make_shared<DrrOptions>();
  auto* cmd = app.add_subcommand("drr", "Render a digitally reconstructed radiograph (line integrals of attenuation)");
  cmd->add_option("--ct", o->ct, "CT volume in HU (.nii, .nii.gz, .mha, .mhd, .nrrd, DICOM directory)")->required();
  cmd->add_option("--camera", o->camera, "Camera JSON (docs/conventions.md)")->required();
  cmd->add_option("--pose", o->pose, "Pose JSON with T_world_ct (default: identity)");
  cmd->add_option("--out", o->out,
                  "Output: .tif/.tiff/.pfm/.nii/.nii.gz raw line integrals, .mha/.nrrd the same with the detector's pixel "
                  "spacing, or .png 16-bit log-domain X-ray")
      ->required();
  cmd->add_option("--backend", o->backend, "reference | cpu | vulkan[:N] (fluoro devices lists the devices)")->capture_default_str();
  cmd->add_option("--step", o->step_mm, "Largest sample spacing along a ray, mm")->capture_default_str();
  cmd->add_option("--mu-water", o->mu_water, "Attenuation of water, 1/mm")->capture_default_str();
  cmd->add_option("--bone-threshold", o->bone_threshold_hu, "Voxels below this HU count as air (bone-only DRR)");
  cmd->add_option("--window", o->window, "Render only pixels X0,Y0,WIDTH,HEIGHT");
  add_physics_options(cmd, o->physics);
  cmd->callback([o] { run(*o); });
}

}  // namespace fluoro::cli
