// fluoro register: CT to X-ray registration (initial pose, coarse contour ICP, fine GPR), the
// result as one JSON document, and validation overlays.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/global_options.hpp"
#include "apps/fluoro/prepared_ct_arguments.hpp"
#include "apps/fluoro/provenance.hpp"
#include "apps/fluoro/result_files.hpp"
#include "apps/fluoro/xray_views.hpp"
#include "engine/backend.hpp"
#include "engine/error.hpp"
#include "pipelines/registration/validation_overlay.hpp"
#include "engine/image_io.hpp"
#include "engine/itk_transform_writer.hpp"
#include "engine/json_io.hpp"
#include "engine/volume_io.hpp"
#include "kernels/backend_registry.hpp"
#include "pipelines/registration/landmarks.hpp"
#include "pipelines/registration/livewire.hpp"
#include "pipelines/registration/registration.hpp"
#include "pipelines/registration/registration_io.hpp"

namespace fluoro::cli {
namespace {

struct RegisterOptions {
  PreparationArguments prep;  // --ct, --mask, --iso, --tissue-hu, --mu-water
  std::string prepared;       // a file of `fluoro prepare` for this CT and these settings
  std::string init, landmarks, contours, out, tfm, overlay_dir, backend = "cpu";
  std::vector<std::string> views;
  bool bone_bright = false, linear = false, no_coarse = false, livewire = false, no_global_search = false;
  std::string polish_correlation = correlation_polish_name(RegistrationOptions{}.correlation_polish);
  double relative_correlation_floor = RegistrationOptions{}.min_relative_correlation;
};

// The effective settings of a run, for the result's provenance: the command's options and the
// registration's stages as they ran (defaults included).
nlohmann::json settings_json(const RegisterOptions& o, const RegistrationOptions& r, const std::string& backend,
                             XrayEncoding encoding) {
  nlohmann::json stages = nlohmann::json::array();
  for (const GprStage& s : r.stages)
    stages.push_back({{"sigma_mm", s.sigma_mm}, {"grid_mm", s.grid_mm}, {"step_mm", s.step_mm}, {"max_pixels", s.max_pixels},
                      {"rotation_step_deg", s.rotation_step_deg}, {"translation_step_mm", s.translation_step_mm},
                      {"max_iterations", s.simplex.max_iterations},
                      {"optimiser", s.optimiser == FineOptimiser::simplex ? "simplex" : "quasi_newton"}});
  return {{"backend", backend},
          {"iso_hu", r.bone_iso_hu},
          {"tissue_hu", r.tissue_hu},
          {"mu_water_per_mm", r.mu_water_per_mm},
          {"xray_encoding", encoding == XrayEncoding::linear ? "linear"
                            : encoding == XrayEncoding::bone_bright ? "bone_bright" : "log_domain"},
          {"initial_pose", o.init.empty() ? "landmarks" : "pose file"},
          {"contours", o.contours.empty() ? "automatic" : (o.livewire ? "livewire" : "traced")},
          {"bone", o.prep.mask.empty() ? "iso-value" : "mask"},
          {"ct_preparation", o.prepared.empty() ? "computed" : "prepared file"},
          {"coarse", r.coarse},
          {"coarse_restarts", r.coarse_restarts},
          {"global_search", r.global_search},
          {"correlation_polish", correlation_polish_name(r.correlation_polish)},
          {"relative_correlation_floor", r.min_relative_correlation},
          {"fine_stages", stages},
          {"views", o.views.size()}};
}

void run(const RegisterOptions& o) {
  check_output_path(o.out);
  if (!o.tfm.empty()) {
    if (!is_itk_transform_path(o.tfm)) throw_input_error(o.tfm, "unsupported transform file extension (use .tfm, .txt, .h5 or .hdf5)");
    check_output_path(o.tfm);
    prepare_itk_transform_writer(o.tfm);  // a missing HDF5 module fails now, not after the registration
  }
  validate_preparation_arguments(o.prep);
  if (o.bone_bright && o.linear) throw_input_error("--bone-bright", "cannot be combined with --linear");
  // One X-ray fixes the pose across its viewing direction but hardly along it (only through the
  // magnification): a registration reported from it could be centimetres off in depth.
  if (o.views.size() < 2)
    throw_input_error("--view", "one X-ray does not fix the depth along its viewing direction; give two or more");
  const XrayEncoding encoding =
      o.linear ? XrayEncoding::linear : (o.bone_bright ? XrayEncoding::bone_bright : XrayEncoding::log_domain);
  std::vector<XrayView> views = read_xray_views(o.views, encoding);
  std::vector<PinholeCamera> cameras;
  for (const auto& v : views) cameras.push_back(v.camera);

  // The initial pose, before the heavy reading, so a bad pose file fails fast.
  Pose initial;
  nlohmann::json initial_doc;
  if (!o.init.empty()) {
    initial = read_pose(o.init);
    initial_doc = {{"source", "pose file"}, {"file", o.init}};
  } else {
    const LandmarkRegistration l = register_landmarks(read_landmarks(o.landmarks, views.size()), cameras, o.landmarks);
    initial = l.registration.transform;
    initial_doc = {{"source", "landmarks"},
                   {"file", o.landmarks},
                   {"landmarks_used", l.ray_distance_mm.size()},
                   {"fre_rms_mm", l.registration.rms_mm},
                   {"fre_max_mm", l.registration.max_mm}};
  }
  std::vector<std::vector<Eigen::Vector2f>> contours;
  if (!o.contours.empty()) {
    std::vector<int> w, h;
    for (const auto& v : views) {
      w.push_back(v.camera.width);
      h.push_back(v.camera.height);
    }
    if (!o.livewire) {
      contours = read_contours(o.contours, w, h);
    } else {
      // Each polyline's vertices are clicks; the livewire joins them along the X-ray's edges.
      const auto polylines = read_contour_polylines(o.contours, w, h);
      contours.resize(views.size());
      for (size_t v = 0; v < views.size(); ++v)
        for (const Polyline& clicks : polylines[v])
          for (const auto& p : livewire_path(views[v].image, clicks)) contours[v].push_back(p);
    }
  } else if (o.livewire) {
    throw_input_error("--livewire", "needs --contours CONTOURS.json (the clicked points)");
  }
  auto backend = make_backend(o.backend);
  RegistrationOptions options = registration_options(o.prep);
  options.coarse = !o.no_coarse;
  options.global_search = !o.no_global_search;
  options.correlation_polish = *correlation_polish_from_name(o.polish_correlation);  // checked by the parser
  options.min_relative_correlation = o.relative_correlation_floor;
  std::shared_ptr<const PreparedCt> ct;
  if (!o.prepared.empty()) {
    // The CT itself is not read: its digest (recorded in the result anyway) proves the prepared
    // file was made from it.
    ct = read_prepared_ct(o.prepared, *backend, prepared_ct_source(o.prep, options), /*digest=*/true);
  } else {
    const Volume hu = read_volume(o.prep.ct);
    std::optional<Volume> mask;
    if (!o.prep.mask.empty()) mask = read_volume(o.prep.mask);
    ct = std::make_shared<const PreparedCt>(prepare_ct(*backend, hu, options, mask ? &*mask : nullptr));
  }
  const PreparedRegistration reg(*backend, ct, views, options, contours);
  const RegistrationReport report = reg.run(initial);

  nlohmann::json doc = report_to_json(report);
  doc["initial"] = initial_doc;
  doc["backend"] = std::string(backend->name());
  doc["preparation_seconds"] = reg.preparation_seconds();
  nlohmann::json inputs = {{"ct", file_digest(o.prep.ct)}};
  if (!o.prepared.empty()) {
    inputs["prepared"] = file_digest(o.prepared);
    doc["prepared_load_seconds"] = ct->seconds;
  }
  if (!o.init.empty()) inputs["init"] = file_digest(o.init);
  if (!o.landmarks.empty()) inputs["landmarks"] = file_digest(o.landmarks);
  for (size_t v = 0; v < o.views.size(); ++v) {
    const auto [image, camera] = split_view_argument(o.views[v]);
    inputs["views"].push_back({{"image", file_digest(image)}, {"camera", file_digest(camera)}});
  }
  if (!o.prep.mask.empty()) inputs["mask"] = file_digest(o.prep.mask);
  if (!o.contours.empty()) inputs["contours"] = file_digest(o.contours);
  doc["inputs"] = inputs;
  doc["provenance"] = provenance("register", settings_json(o, options, std::string(backend->name()), encoding), inputs);

  if (!o.overlay_dir.empty()) {
    namespace fs = std::filesystem;
    fs::create_directories(o.overlay_dir);
    for (size_t v = 0; v < views.size(); ++v) {
      float lo = views[v].image.pixels[0], hi = lo;
      for (float p : views[v].image.pixels) lo = std::min(lo, p), hi = std::max(hi, p);
      // Red: the CT's expected edges at the initial pose; green: at the registered pose.
      const auto rgb = validation_overlay(*backend, reg.fine_gradient(), views[v].camera, views[v].image, lo, hi,
                                          report.initial, report.pose);
      const std::string path = (fs::path(o.overlay_dir) / ("view" + std::to_string(v + 1) + "_" +
                                                           fs::path(views[v].name).stem().string() + "_overlay.png"))
                                   .string();
      write_png_u8(rgb, views[v].camera.width, views[v].camera.height, 3, path);
      doc["overlays"].push_back(path);
    }
  }
  // The transform only for a registration that succeeded: a failed pose is never handed on.
  if (!o.tfm.empty() && report.ok) {
    write_itk_transform(report.pose, o.tfm);
    doc["itk_transform"] = {{"path", o.tfm}, {"holds", "T_ct_world (ITK: fixed = world, moving = CT)"}};
  }
  write_json(doc, o.out);
  if (!quiet()) {
    std::printf("%s: status %s, score %.4g, gradient correlation %.2f (views %s)%s, %.2f s (+%.2f s preparation)\n",
                o.out.c_str(), report.ok ? "ok" : "failed", report.score, report.gradient_correlation,
                format_view_correlations(report).c_str(), report.confident ? "" : " (likely failure)", report.seconds,
                reg.preparation_seconds());
    for (const auto& s : report.stages)
      std::printf("  %-7s %.3f s, %d iterations, %d evaluations\n", s.name.c_str(), s.seconds, s.iterations,
                  s.evaluations);
  }
  if (!report.ok) throw MethodFailed(o.out + ": registration failed: " + report.failure_reason);
}

}  // namespace

void add_register_command(CLI::App& app) {
  auto o = std::make_shared<RegisterOptions>();
  auto* cmd = app.add_subcommand("register", "Register a CT to calibrated X-rays (coarse contour ICP, then fine GPR)");
  cmd->add_option("--ct", o->prep.ct, "CT volume in HU (.nii, .nii.gz, .mha, .mhd, .nrrd, DICOM directory)")->required();
  cmd->add_option("--view", o->views, "XRAY:CAMERA.json, one per X-ray (two or more)")->required();
  auto* init = cmd->add_option("--init", o->init, "Initial pose JSON (T_world_ct)");
  auto* lm = cmd->add_option("--landmarks", o->landmarks, "Landmarks JSON: CT points and their X-ray pixels");
  init->excludes(lm);
  cmd->add_option("--contours", o->contours, "Bone contours JSON traced on the X-rays (default: automatic)");
  cmd->add_flag("--livewire", o->livewire,
                "The contours' polyline vertices are clicks, joined along the X-ray's edges (IntelligentScissorsMB)");
  cmd->add_option("--mask", o->prep.mask, "Bone mask volume (non-zero = bone), replaces the iso-value");
  cmd->add_option("--prepared", o->prepared,
                  "Prepared CT file of `fluoro prepare` for this --ct (its digest is checked): skips the CT's preparation");
  cmd->add_option("--out", o->out, "Result JSON")->required();
  cmd->add_option("--tfm", o->tfm,
                  "Also write the registered pose as an ITK transform file (.tfm/.txt text, .h5/.hdf5; holds the "
                  "world-to-CT map, ITK's fixed-to-moving direction)");
  cmd->add_option("--overlay-dir", o->overlay_dir, "Write expected-edge overlays (initial red, final green) here");
  cmd->add_option("--backend", o->backend, "Compute backend (reference | cpu | vulkan[:N])")->capture_default_str();
  add_preparation_options(*cmd, o->prep);
  cmd->add_flag("--bone-bright", o->bone_bright, "X-rays are display-inverted (bone bright)");
  cmd->add_flag("--linear", o->linear, "X-rays are raw detector intensities (the log is taken)");
  cmd->add_flag("--no-coarse", o->no_coarse, "Skip the coarse contour step");
  cmd->add_flag("--no-global-search", o->no_global_search,
                "Never run the coarse step's global search (rotations about the bone centre, each view's shift by FFT "
                "correlation), which runs only when the ICP from the start does not correlate (docs/registration.md)");
  // A flag that may take a value: alone it gives "true", which means on, as when it was a plain
  // flag (whose =true and =false still mean on and off).
  cmd->add_flag("--polish-correlation", o->polish_correlation,
                "After the GPR stages, maximise the gradient correlation: auto (default) where the X-rays depart from "
                "the DRR model or the GPR's pose lies off the correlation's peak (real fluoroscopy: scatter, beam "
                "hardening, detector blur flatten the GPR's optimum), on (always; about 1.4-1.9x the time on a real CT) "
                "or off (docs/registration.md)")
      ->option_text("[=auto|on|off]")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, std::string>{{"auto", "auto"}, {"on", "on"}, {"off", "off"}, {"true", "on"}, {"false", "off"}}));
  cmd->add_option("--relative-correlation-floor", o->relative_correlation_floor,
                  "Not confident when a view correlates under this fraction of what an X-ray of the whole CT would at the "
                  "result (0: off; lower it for X-rays with much the CT lacks, docs/registration.md)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  cmd->callback([o] {
    if (o->init.empty() && o->landmarks.empty()) throw_input_error("register", "give --init POSE.json or --landmarks LM.json");
    run(*o);
  });
}

}  // namespace fluoro::cli
