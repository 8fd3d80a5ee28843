// fluoro demo: the whole engine on an embedded phantom. Builds a femur CT, renders two C-arm
// views at a known pose, computes the gradient field, and shows that the gradient projection
// score and the expected-edge overlay single out the true pose against a perturbed one.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "datasets/c_arm.hpp"
#include "datasets/phantom.hpp"
#include "engine/attenuation.hpp"
#include "engine/backend.hpp"
#include "engine/error.hpp"
#include "engine/expected_edges.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "engine/xray.hpp"
#include "pipelines/registration/edge_pixels.hpp"

namespace fluoro::cli {
namespace {

struct DemoOptions {
  std::string out_dir = "out/demo", backend = "cpu";
  int size = 128;
};

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

void run(const DemoOptions& o) {
  if (o.size < 32 || o.size > 512) throw_input_error("--size " + std::to_string(o.size), "must be 32 to 512");
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(o.out_dir, ec);
  if (ec || !fs::is_directory(o.out_dir)) throw_input_error("--out-dir " + o.out_dir, "cannot create the directory");
  const fs::path dir(o.out_dir);
  nlohmann::json summary;
  auto t = std::chrono::steady_clock::now();

  PhantomParams pp;
  pp.kind = PhantomKind::femur;
  pp.size = o.size;
  const Phantom phantom = make_phantom(pp);
  const Volume mu = hu_to_attenuation(phantom.hu);
  summary["timings_s"]["phantom"] = seconds_since(t);

  auto backend = make_backend(o.backend);
  t = std::chrono::steady_clock::now();
  const auto device_mu = backend->upload(mu);
  // The registration side sees bone only (voxels under 200 HU as air), as a bone model from the
  // pre-operative CT would be: soft tissue edges are not what the overlay and the score are for.
  const auto bone = backend->upload(hu_to_attenuation(phantom.hu, {0.02, 200.0}));
  const auto gradient = backend->gradient_field(*bone, {1.0, 0.0});
  summary["timings_s"]["upload_and_gradient_field"] = seconds_since(t);

  const CArmGeometry geometry;
  const PinholeCamera views[] = {c_arm_view(geometry, 0), c_arm_view(geometry, 90)};
  const char* view_names[] = {"ap", "lateral"};
  const Pose truth = pose_from_rotation_vector(Eigen::Vector3d(0.05, -0.03, 0.10), Eigen::Vector3d(4, -3, 6));
  const Pose perturbed = pose_from_rotation_vector(Eigen::Vector3d(0.03, 0.04, 0.05), Eigen::Vector3d(3, 2, -4)) * truth;

  t = std::chrono::steady_clock::now();
  const auto drrs = backend->drr(*device_mu, std::span(&truth, 1), views, DrrParams{0.5, {}});
  summary["timings_s"]["drr_2_views"] = seconds_since(t);

  std::vector<EdgePixels> edges;
  for (int v = 0; v < 2; ++v) {
    const std::string base = (dir / view_names[v]).string();
    write_drr(drrs[size_t(v)], base + "_drr.png");
    write_float_image(drrs[size_t(v)], base + "_drr.tif");
    write_camera(views[v], base + "_camera.json");
    // The DRR as a log-domain X-ray, as a C-arm would deliver it.
    const Image xray = drr_to_xray(drrs[size_t(v)], display_mapping(drrs[size_t(v)], 1000.0));
    edges.push_back(detect_edge_pixels(xray, XrayPolarity::log_domain, {}, base));
    summary["views"][view_names[v]] = {{"camera", base + "_camera.json"}, {"drr_png", base + "_drr.png"},
                                       {"drr_tif", base + "_drr.tif"}, {"edge_pixels", edges.back().pixels.size()},
                                       {"overlay", base + "_overlay.png"}};
  }
  write_pose(truth, (dir / "truth_pose.json").string());
  write_pose(perturbed, (dir / "perturbed_pose.json").string());

  t = std::chrono::steady_clock::now();
  const Pose poses[] = {truth, perturbed};
  const auto scores = backend->gpr_score(*gradient, poses, views, edges, GprParams{});
  summary["timings_s"]["gpr_score_2_poses"] = seconds_since(t);
  summary["gpr_score"] = {{"truth", scores[0]}, {"perturbed", scores[1]}};

  t = std::chrono::steady_clock::now();
  for (int v = 0; v < 2; ++v) {
    const auto at_truth = expected_edges(*backend, *gradient, truth, views[v]);
    const auto at_perturbed = expected_edges(*backend, *gradient, perturbed, views[v]);
    const Image xray = drr_to_xray(drrs[size_t(v)], display_mapping(drrs[size_t(v)], 255.0));
    // Red: expected edges at the perturbed pose; green: at the true pose, over the X-ray.
    const auto rgb = overlay_rgb(xray, 0, 255, {{&at_perturbed.mask, 255, 40, 40}, {&at_truth.mask, 40, 255, 40}});
    write_png_u8(rgb, views[v].width, views[v].height, 3, (dir / (std::string(view_names[v]) + "_overlay.png")).string());
  }
  summary["timings_s"]["expected_edge_overlays"] = seconds_since(t);
  summary["backend"] = std::string(backend->name());
  summary["phantom"] = {{"kind", "femur"}, {"size", o.size}, {"spacing_mm", mu.geometry.spacing.x()}};
  summary["truth_pose"] = (dir / "truth_pose.json").string();
  summary["status"] = "ok";
  const std::string summary_path = (dir / "summary.json").string();
  write_json(summary, summary_path);

  std::printf("fluoro demo: femur phantom %d^3, two C-arm views (AP, lateral), backend %s\n", o.size,
              std::string(backend->name()).c_str());
  std::printf("  GPR score at the true pose %.4g, at a pose perturbed by %.1f deg / %.1f mm: %.4g\n", scores[0],
              rotation_angle_deg(perturbed * truth.inverse()), (perturbed * truth.inverse()).translation().norm(),
              scores[1]);
  std::printf("  DRRs:      %s/{ap,lateral}_drr.png (.tif raw)\n", o.out_dir.c_str());
  std::printf("  overlays:  %s/{ap,lateral}_overlay.png (green: expected edges at the true pose, red: perturbed)\n",
              o.out_dir.c_str());
  std::printf("  summary:   %s\n", summary_path.c_str());
}

}  // namespace

void add_demo_command(CLI::App& app) {
  auto o = std::make_shared<DemoOptions>();
  auto* cmd = app.add_subcommand("demo", "Run the engine end to end on an embedded femur phantom");
  cmd->add_option("--out-dir", o->out_dir, "Where the PNGs and JSON go")->capture_default_str();
  cmd->add_option("--size", o->size, "Phantom voxels per side")->capture_default_str();
  cmd->add_option("--backend", o->backend, "reference | cpu | vulkan[:N] (fluoro devices lists the devices)")->capture_default_str();
  cmd->callback([o] { run(*o); });
}

}  // namespace fluoro::cli
