// fluoro demo: the whole registration story on an embedded femur phantom. Builds the CT, renders
// three C-arm X-rays at a known pose, starts from a pose 9.5 mm away (mean surface distance, the
// seed's simulation experiment), registers (coarse contour ICP, fine GPR), and writes the X-rays,
// cameras, poses, result and validation overlays, with a short error report.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/physics_options.hpp"
#include "apps/fluoro/provenance.hpp"
#include "apps/fluoro/result_files.hpp"
#include "apps/fluoro/demo_calibration.hpp"
#include "apps/fluoro/demo_distal_locking.hpp"
#include "datasets/c_arm.hpp"
#include "datasets/phantom.hpp"
#include "engine/attenuation.hpp"
#include "engine/backend.hpp"
#include "engine/error.hpp"
#include "pipelines/registration/validation_overlay.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "engine/xray.hpp"
#include "kernels/backend_registry.hpp"
#include "pipelines/registration/error_metrics.hpp"
#include "pipelines/registration/registration.hpp"
#include "pipelines/registration/registration_io.hpp"
#include "pipelines/registration/start_poses.hpp"

namespace fluoro::cli {
namespace {

struct DemoOptions {
  std::string out_dir, backend = "cpu";
  int size = 128, pixels = 0;  // 0: 512 for the registration, 1024 for the calibration
  double start_mm = 9.5;
  bool calibration = false, ring = false, distal_locking = false, interactive = false;
  double tilt_deg = 8;
  double orbit_deg = 30;
  XrayPhysics physics;  // applied to the registration demo's X-rays
};

nlohmann::json errors_json(const RegistrationErrors& e) {
  return {{"surface_tre_mean_mm", e.surface_tre_mean_mm}, {"surface_tre_max_mm", e.surface_tre_max_mm},
          {"fiducial_tre_mean_mm", e.fiducial_tre_mean_mm}, {"mpd_mm", e.mpd_mm},
          {"rotation_deg", e.rotation_deg}, {"translation_mm", e.translation_mm}};
}

void run_registration_demo(const DemoOptions& o) {
  if (o.size < 48 || o.size > 256) throw_input_error("--size " + std::to_string(o.size), "must be 48 to 256");
  if (!(o.start_mm > 0 && o.start_mm <= 100)) throw_input_error("--start-mm", "must be in (0, 100]");
  check_physics_options(o.physics);
  namespace fs = std::filesystem;
  make_output_directory(o.out_dir);
  const fs::path dir(o.out_dir);
  nlohmann::json summary;
  auto t = std::chrono::steady_clock::now();

  PhantomParams pp;
  pp.kind = PhantomKind::femur;
  pp.size = o.size;
  pp.fiducials = true;  // for the fiducial TRE; they are in the CT and the X-rays alike
  const Phantom phantom = make_phantom(pp);
  summary["timings_s"]["phantom"] = seconds_since(t);
  auto backend = make_backend(o.backend);

  // The truth: the bone near the isocentre, turned a little; three C-arm views of it.
  const std::vector<Eigen::Vector3d> surface = surface_points(phantom.hu, 250, 2000);
  const Pose truth = pose_from_rotation_vector(Eigen::Vector3d(0.05, -0.03, 0.10), Eigen::Vector3d(4, -3, 6));
  CArmGeometry geometry;
  geometry.pixels = o.pixels;
  geometry.pixel_mm = 0.6 * 512.0 / o.pixels;
  const std::vector<std::pair<std::string, PinholeCamera>> cams = {{"ap", c_arm_view(geometry, 0)},
                                                                   {"oblique60", c_arm_view(geometry, 60)},
                                                                   {"lateral_tilted", c_arm_view(geometry, 100, 15)}};
  t = std::chrono::steady_clock::now();
  std::vector<PinholeCamera> cameras;
  for (const auto& c : cams) cameras.push_back(c.second);
  const auto mu = backend->upload(hu_to_attenuation(phantom.hu));
  auto drrs = backend->drr(*mu, std::span(&truth, 1), cameras, DrrParams{0.5, {}});
  if (o.physics.any())  // scatter, beam hardening, blur, noise: X-rays that do not follow the registration's model
    for (size_t v = 0; v < drrs.size(); ++v) {
      XrayPhysics p = o.physics;
      p.seed = o.physics.seed * 7919u + v;  // each view its own noise
      drrs[v] = simulate_xray_physics(drrs[v], p);
    }
  summary["timings_s"]["render_x_rays"] = seconds_since(t);

  std::vector<XrayView> views;
  for (size_t v = 0; v < cams.size(); ++v) {
    const std::string base = (dir / cams[v].first).string();
    write_drr(drrs[v], base + "_xray.png");  // a 16-bit log-domain X-ray, the default input
    write_camera(cams[v].second, base + "_camera.json");
    views.push_back({base + "_xray.png", drr_to_xray(drrs[v], display_mapping(drrs[v], 1000.0)), cams[v].second});
  }
  write_pose(truth, (dir / "truth_pose.json").string());

  // A start 9.5 mm from the truth, as the seed's simulation experiment.
  const Eigen::Vector3d centre_ct = mean_point(surface);
  const Pose start = start_pose_at_distance(truth, surface, centre_ct, o.start_mm, 2026);
  write_pose(start, (dir / "start_pose.json").string());

  const PreparedRegistration reg(*backend, phantom.hu, views);
  const RegistrationReport report = reg.run(start);
  summary["timings_s"]["registration_preparation"] = reg.preparation_seconds();
  nlohmann::json result = report_to_json(report);
  // No input files: the demo made its CT and X-rays in memory (and wrote them for a rerun).
  const nlohmann::json origin = provenance(
      "demo", {{"size", o.size}, {"pixels", o.pixels}, {"start_mm", o.start_mm}, {"backend", o.backend},
               {"physics", physics_settings(o.physics)}},
      nlohmann::json::array());
  result["provenance"] = origin;
  write_json(result, (dir / "result.json").string());

  const RegistrationErrors before = registration_errors(start, truth, surface, phantom.fiducials, cameras);
  const RegistrationErrors after = registration_errors(report.pose, truth, surface, phantom.fiducials, cameras);
  for (size_t v = 0; v < views.size(); ++v) {
    const Image display = drr_to_xray(drrs[v], display_mapping(drrs[v], 255.0));
    // Red: the CT's expected edges at the start; green: at the registered pose.
    const auto rgb = validation_overlay(*backend, reg.fine_gradient(), cameras[v], display, 0, 255, start, report.pose);
    write_png_u8(rgb, cameras[v].width, cameras[v].height, 3, (dir / (cams[v].first + "_overlay.png")).string());
  }
  summary["backend"] = std::string(backend->name());
  summary["phantom"] = {{"kind", "femur"}, {"size", o.size}, {"spacing_mm", phantom.hu.geometry.spacing.x()}};
  summary["errors"] = {{"start", errors_json(before)}, {"registered", errors_json(after)}};
  summary["registration"] = result;
  summary["status"] = report.ok ? "ok" : "failed";
  summary["provenance"] = origin;
  const std::string summary_path = (dir / "summary.json").string();
  write_json(summary, summary_path);

  std::printf("fluoro demo: femur phantom %d^3 (%.1f mm voxels), three %dx%d C-arm X-rays, backend %s\n", o.size,
              phantom.hu.geometry.spacing.x(), o.pixels, o.pixels, std::string(backend->name()).c_str());
  std::printf("  start:      surface TRE %.2f mm (max %.2f), fiducial TRE %.2f mm, %.2f deg / %.2f mm off\n",
              before.surface_tre_mean_mm, before.surface_tre_max_mm, before.fiducial_tre_mean_mm, before.rotation_deg,
              before.translation_mm);
  std::printf("  registered: surface TRE %.3f mm (max %.3f), fiducial TRE %.3f mm, mPD %.3f mm, %.3f deg / %.3f mm off\n",
              after.surface_tre_mean_mm, after.surface_tre_max_mm, after.fiducial_tre_mean_mm, after.mpd_mm,
              after.rotation_deg, after.translation_mm);
  std::printf("  status %s, gradient correlation %.2f (views %s; %s), %.2f s (+%.2f s preparation):",
              report.ok ? "ok" : "failed", report.gradient_correlation, format_view_correlations(report).c_str(),
              report.confident ? "confident" : "likely failure", report.seconds, reg.preparation_seconds());
  for (const auto& s : report.stages) std::printf(" %s %.2f s;", s.name.c_str(), s.seconds);
  std::printf("\n  X-rays:     %s/*_xray.png (16-bit, log domain) with *_camera.json\n", o.out_dir.c_str());
  std::printf("  overlays:   %s/*_overlay.png (red: expected edges at the start, green: registered)\n",
              o.out_dir.c_str());
  std::printf("  result:     %s/result.json; summary: %s\n", o.out_dir.c_str(), summary_path.c_str());
  std::printf("  again:      fluoro register --ct CT --view %s/ap_xray.png:%s/ap_camera.json ... --init %s/start_pose.json\n",
              o.out_dir.c_str(), o.out_dir.c_str(), o.out_dir.c_str());
}

void run(DemoOptions o) {
  if (o.calibration && o.distal_locking) throw_input_error("demo", "give at most one of --calibration and --distal-locking");
  if (o.pixels == 0) o.pixels = o.calibration || o.distal_locking ? 1024 : 512;
  if (o.pixels < 128 || o.pixels > 1024) throw_input_error("--pixels " + std::to_string(o.pixels), "must be 128 to 1024");
  if ((o.calibration || o.distal_locking) && o.physics.any())
    throw_input_error("demo", "the imaging-physics options apply to the registration demo only");
  if (o.calibration) {
    if (!std::isfinite(o.orbit_deg)) throw_input_error("--orbit", "must be a number");
    run_calibration_demo({o.out_dir.empty() ? "out/demo_calibration" : o.out_dir, o.pixels, o.orbit_deg, o.ring});
  } else if (o.distal_locking) {
    if (!(o.tilt_deg >= 0 && o.tilt_deg <= 30)) throw_input_error("--tilt", "must be 0 to 30 degrees");
    run_distal_locking_demo({o.out_dir.empty() ? "out/demo_distal_locking" : o.out_dir, o.pixels, o.tilt_deg, o.interactive});
  } else {
    if (o.out_dir.empty()) o.out_dir = "out/demo";
    run_registration_demo(o);
  }
}

}  // namespace

void add_demo_command(CLI::App& app) {
  auto o = std::make_shared<DemoOptions>();
  auto* cmd = app.add_subcommand("demo", "Register an embedded femur phantom to three simulated X-rays, end to end "
                                         "(--calibration: dewarp and calibrate a generated C-arm instead; "
                                         "--distal-locking: locate a drill guide and a nail, and the robot's goal)");
  cmd->add_option("--out-dir", o->out_dir, "Where the PNGs and JSON go (default out/demo, out/demo_calibration, out/demo_distal_locking)");
  cmd->add_flag("--calibration", o->calibration,
                "The calibration chain instead: a dewarp grid and a phantom X-ray, dewarp, calibrate, errors against the truth");
  cmd->add_option("--orbit", o->orbit_deg, "With --calibration: the C-arm orientation (deg), which sets the distortion")
      ->capture_default_str();
  cmd->add_flag("--ring", o->ring, "With --calibration: the denser ring phantom instead of the seed's tower");
  cmd->add_flag("--distal-locking", o->distal_locking,
                "Distal locking instead: a drill guide and a nail in one X-ray, both poses, the robot's goal, errors against the truth");
  cmd->add_option("--tilt", o->tilt_deg, "With --distal-locking: angle between the hole axes and the ray through the nail (deg)")
      ->capture_default_str();
  cmd->add_flag("--interactive", o->interactive, "With --distal-locking: the seed's fronto-parallel nail pose instead of the generic fit");
  cmd->add_option("--size", o->size, "Phantom voxels per side")->capture_default_str();
  cmd->add_option("--pixels", o->pixels, "X-ray pixels per side (default 512; 1024 with --calibration or --distal-locking)");
  cmd->add_option("--start-mm", o->start_mm, "Start pose distance from the truth (mean surface TRE, mm)")
      ->capture_default_str();
  cmd->add_option("--backend", o->backend, "reference | cpu | vulkan[:N] (fluoro devices lists the devices)")->capture_default_str();
  add_physics_options(cmd, o->physics);
  cmd->callback([o] { run(*o); });
}

}  // namespace fluoro::cli
