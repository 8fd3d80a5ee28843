#include "kernels/backend_registry.hpp"
#include "pipelines/sweep/sweep.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <mutex>
#include <random>
#include <sstream>
#include <stdexcept>

#include "engine/attenuation.hpp"
#include "engine/error.hpp"
#include "engine/json_io.hpp"
#include "engine/sha256.hpp"
#include "engine/volume_io.hpp"
#include "engine/xray.hpp"
#include "pipelines/registration/apparent_contour.hpp"
#include "pipelines/registration/error_metrics.hpp"
#include "pipelines/registration/nearest_point_map.hpp"
#include "pipelines/registration/prepared_ct_file.hpp"
#include "pipelines/registration/start_poses.hpp"

namespace fluoro {
namespace {

double get_number(const nlohmann::json& j, const char* key, double fallback, const std::string& path) {
  if (!j.contains(key)) return fallback;
  if (!j[key].is_number() || !std::isfinite(j[key].get<double>()))
    throw_input_error(path, std::string("\"") + key + "\" must be a number");
  return j[key].get<double>();
}

// An integer field, whole and within [lo, hi]; casting an unchecked double (1e300) to int is
// undefined behaviour (fuzz_sweep_config found it).
int64_t get_integer(const nlohmann::json& j, const char* key, int64_t fallback, int64_t lo, int64_t hi,
                    const std::string& path) {
  const double v = get_number(j, key, double(fallback), path);
  if (!(v >= double(lo) && v <= double(hi)) || v != std::floor(v))
    throw_input_error(path, std::string("\"") + key + "\" must be a whole number from " + std::to_string(lo) + " to " +
                                std::to_string(hi));
  return int64_t(v);
}

// A metal rod (3000 HU, 3 mm radius, 120 mm long) through a point 25 mm beside the bone centre,
// oblique to every axis: a surgical tool in the X-rays that the CT does not have.
Volume with_metal_rod(Volume hu, const Eigen::Vector3d& bone_centre) {
  const Eigen::Vector3d p = bone_centre + Eigen::Vector3d(25, -10, 0);
  const Eigen::Vector3d d = Eigen::Vector3d(1, 2, 3).normalized();
  const VolumeGeometry& g = hu.geometry;
  for (int k = 0; k < g.size.z(); ++k)
    for (int j = 0; j < g.size.y(); ++j)
      for (int i = 0; i < g.size.x(); ++i) {
        const Eigen::Vector3d x = g.index_to_physical(Eigen::Vector3d(i, j, k)) - p;
        const double along = x.dot(d);
        if (std::abs(along) <= 60 && (x - along * d).norm() <= 3.0) hu.at(i, j, k) = 3000.0f;
      }
  return hu;
}

// SWEEP.json's "physics" object (docs/cli.md). Unknown keys are refused: a misspelt effect would
// otherwise run a sweep without it.
XrayPhysics read_physics(const nlohmann::json& j, const std::string& path) {
  if (!j.is_object()) throw_input_error(path, "\"physics\" must be an object");
  static const char* const keys[] = {"beam_hardening", "scatter", "scatter_sigma_px", "blur_px", "photons", "max_line_integral"};
  for (const auto& [key, value] : j.items())
    if (std::find_if(std::begin(keys), std::end(keys), [&key = key](const char* k) { return key == k; }) == std::end(keys))
      throw_input_error(path, "\"physics\" has an unknown key \"" + key +
                                  "\" (beam_hardening, scatter, scatter_sigma_px, blur_px, photons, max_line_integral)");
  XrayPhysics p;
  p.beam_hardening = get_number(j, "beam_hardening", 0, path);
  p.scatter_to_primary = get_number(j, "scatter", 0, path);
  p.scatter_sigma_px = get_number(j, "scatter_sigma_px", 0, path);
  p.blur_px = get_number(j, "blur_px", 0, path);
  p.photons = get_number(j, "photons", 0, path);
  p.max_line_integral = get_number(j, "max_line_integral", p.max_line_integral, path);
  if (const auto bad = xray_physics_problem(p))
    throw_input_error(path, "\"physics\": \"" + bad->key + "\" " + bad->problem);
  return p;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

std::vector<std::vector<Eigen::Vector2f>> simulated_traced_contours(const BoneMesh& mesh, const std::vector<XrayView>& views,
                                                                    const Pose& truth, const EdgeDetectionParams& edges) {
  std::vector<std::vector<Eigen::Vector2f>> traced;
  for (const auto& v : views) {
    std::vector<Eigen::Vector2f> outline;
    for (const auto& c : apparent_contour(mesh, truth.inverse() * v.camera.source()))
      outline.push_back(v.camera.project(truth * c.point).cast<float>());
    const NearestPointMap near(outline, v.camera.width, v.camera.height);
    traced.emplace_back();
    for (const auto& p : detect_edge_pixels(v.image, XrayPolarity::log_domain, edges, v.name).pixels) {
      const int k = near.nearest(p.x(), p.y());
      if (k >= 0 && (outline[size_t(k)] - p).norm() <= 2.0f) traced.back().push_back(p);
    }
  }
  return traced;
}

namespace {
SweepConfig parse_sweep_config(const std::string& path);
}  // namespace

// A value of the wrong type that a field's own check does not name (nlohmann's type_error, which
// escaped and aborted: fuzz_sweep_config) is bad input naming the file, like every other mistake.
SweepConfig read_sweep_config(const std::string& path) {
  try {
    return parse_sweep_config(path);
  } catch (const nlohmann::json::type_error& e) {
    throw_input_error(path, std::string("a value has the wrong type (") + e.what() + ")");
  }
}

namespace {
SweepConfig parse_sweep_config(const std::string& path) {
  const nlohmann::json j = read_json(path);
  if (!j.is_object()) throw_input_error(path, "expected a JSON object");
  SweepConfig c;
  if (j.contains("ct")) {
    if (!j["ct"].is_string()) throw_input_error(path, "\"ct\" must be a path");
    c.ct_path = j["ct"].get<std::string>();
    // Relative paths are relative to the config file.
    if (!c.ct_path.empty() && c.ct_path[0] != '/')
      c.ct_path = (std::filesystem::path(path).parent_path() / c.ct_path).string();
  } else if (j.contains("phantom")) {
    const auto& p = j["phantom"];
    if (!p.is_object()) throw_input_error(path, "\"phantom\" must be an object");
    // parse_phantom_kind names the command-line option; here the file is what is wrong.
    if (p.contains("kind") && !p["kind"].is_string())
      throw_input_error(path, "\"phantom\" \"kind\" must be \"femur\", \"pelvis\" or \"head\"");
    try {
      c.phantom.kind = parse_phantom_kind(p.value("kind", std::string("femur")));
    } catch (const InputError&) {
      throw_input_error(path, "\"phantom\" \"kind\" must be \"femur\", \"pelvis\" or \"head\"");
    }
    c.phantom.size = int(get_integer(p, "size", 128, 8, 2048, path));
    c.phantom.seed = uint64_t(get_integer(p, "seed", 1, 0, int64_t(1) << 53, path));
    c.phantom.fiducials = p.value("fiducials", false);
  } else {
    throw_input_error(path, "give \"ct\": a CT file, or \"phantom\": {\"kind\": \"femur\", \"size\": 128}");
  }
  if (j.contains("mask")) c.mask_path = j["mask"].get<std::string>();
  if (j.contains("prepared")) {
    if (!j["prepared"].is_string()) throw_input_error(path, "\"prepared\" must be a path");
    c.prepared_path = j["prepared"].get<std::string>();
    if (!c.prepared_path.empty() && c.prepared_path[0] != '/')
      c.prepared_path = (std::filesystem::path(path).parent_path() / c.prepared_path).string();
  }
  if (j.contains("c_arm")) {
    const auto& a = j["c_arm"];
    c.c_arm.source_to_isocentre_mm = get_number(a, "source_to_isocentre_mm", c.c_arm.source_to_isocentre_mm, path);
    c.c_arm.source_to_detector_mm = get_number(a, "source_to_detector_mm", c.c_arm.source_to_detector_mm, path);
    c.c_arm.pixels = int(get_integer(a, "pixels", c.c_arm.pixels, 16, 4096, path));
    c.c_arm.pixel_mm = get_number(a, "pixel_mm", c.c_arm.pixel_mm, path);
    if (!(c.c_arm.pixel_mm > 0)) throw_input_error(path, "\"c_arm\": pixel_mm must be positive");
  }
  if (j.contains("views")) {
    if (!j["views"].is_array() || j["views"].size() < 1 || j["views"].size() > 8)
      throw_input_error(path, "\"views\" must list 1 to 8 views");
    c.views.clear();
    for (const auto& v : j["views"]) c.views.emplace_back(get_number(v, "orbit_deg", 0, path), get_number(v, "tilt_deg", 0, path));
  }
  if (j.contains("truth")) {
    c.truth = pose_from_matrix([&] {
      Eigen::Matrix4d m;
      const auto& t = j["truth"];
      if (!t.is_array() || t.size() != 4) throw_input_error(path, "\"truth\" must be a 4x4 matrix");
      for (int r = 0; r < 4; ++r)
        for (int k = 0; k < 4; ++k) {
          if (!t[size_t(r)].is_array() || t[size_t(r)].size() != 4 || !t[size_t(r)][size_t(k)].is_number())
            throw_input_error(path, "\"truth\" must be a 4x4 matrix");
          m(r, k) = t[size_t(r)][size_t(k)].get<double>();
        }
      return m;
    }(), path);
  }
  if (j.contains("distances_mm")) {
    const auto& d = j["distances_mm"];
    c.from_mm = get_number(d, "from", c.from_mm, path);
    c.to_mm = get_number(d, "to", c.to_mm, path);
    c.step_mm = get_number(d, "step", c.step_mm, path);
  }
  if (!(c.from_mm > 0) || !(c.to_mm >= c.from_mm) || !(c.step_mm > 0) || (c.to_mm - c.from_mm) / c.step_mm > 1e5)
    throw_input_error(path, "\"distances_mm\" needs 0 < from <= to and a positive step");
  c.runs_per_distance = int(get_integer(j, "runs_per_distance", c.runs_per_distance, 1, 1000000, path));
  // plan_sweep holds every run in memory and numbers them with an int.
  if (double(sweep_distance_bins(c)) * c.runs_per_distance > double(kMaxSweepRuns))
    throw_input_error(path, "more than 10 million runs (distance bins x runs_per_distance)");
  const std::string contours = j.value("contours", std::string("traced"));
  if (contours == "traced") c.contours = SweepContours::traced;
  else if (contours == "automatic") c.contours = SweepContours::automatic;
  else throw_input_error(path, "\"contours\" must be \"traced\" or \"automatic\"");
  c.noise = get_number(j, "noise", 0, path);
  if (c.noise < 0 || c.noise > 100) throw_input_error(path, "\"noise\" must be 0 to 100 (a fraction of the X-ray's range)");
  c.metal_tool = j.value("metal_tool", false);
  if (j.contains("physics")) c.physics = read_physics(j["physics"], path);
  if (j.contains("correlation_polish")) {
    // true and false as before the automatic mode; "on", "off" or "auto" as `register --polish-correlation`.
    const nlohmann::json& v = j["correlation_polish"];
    std::optional<CorrelationPolish> mode;
    if (v.is_boolean()) mode = v.get<bool>() ? CorrelationPolish::always : CorrelationPolish::off;
    else if (v.is_string()) mode = correlation_polish_from_name(v.get<std::string>());
    if (!mode) throw_input_error(path, "\"correlation_polish\" must be \"auto\", \"on\", \"off\", true or false");
    c.correlation_polish = *mode;
  }
  if (j.contains("global_search")) {
    if (!j["global_search"].is_boolean()) throw_input_error(path, "\"global_search\" must be true or false");
    c.global_search = j["global_search"].get<bool>();
  }
  c.backend = j.value("backend", c.backend);
  c.seed = uint64_t(get_integer(j, "seed", 1, 0, int64_t(1) << 53, path));
  c.iso_hu = get_number(j, "iso_hu", c.iso_hu, path);
  c.tissue_hu = get_number(j, "tissue_hu", c.tissue_hu, path);
  return c;
}
}  // namespace

int64_t sweep_distance_bins(const SweepConfig& c) {
  const double bins = std::floor((c.to_mm - c.from_mm) / c.step_mm + 1e-9) + 1;
  // A config read_sweep_config did not check (a step of 0, NaN, to < from) has no bins to give.
  if (!(bins >= 0 && bins <= double(kMaxSweepRuns) + 1)) return bins > 0 ? kMaxSweepRuns + 1 : 0;
  return int64_t(bins);
}

std::vector<SweepRun> plan_sweep(const SweepConfig& c) {
  std::vector<SweepRun> runs;
  const int64_t bins = sweep_distance_bins(c);
  if (bins < 1 || c.runs_per_distance < 1 || double(bins) * c.runs_per_distance > double(kMaxSweepRuns))
    throw std::invalid_argument("plan_sweep: a sweep of 1 to 10 million runs");
  for (int b = 0; b < bins; ++b)
    for (int k = 0; k < c.runs_per_distance; ++k) {
      const int index = int(runs.size());
      runs.push_back({index, c.from_mm + b * c.step_mm, c.seed * 1000003ull + uint64_t(index)});
    }
  return runs;
}

SweepScene::SweepScene(const SweepConfig& config) : config_(config) {
  const auto t0 = std::chrono::steady_clock::now();
  backend_ = make_backend(config.backend);
  if (!config.prepared_path.empty() && config.ct_path.empty())
    throw_input_error(config.prepared_path, "a prepared CT needs the sweep's \"ct\" it was prepared from, not a phantom");
  Phantom phantom;
  if (config.ct_path.empty()) phantom = make_phantom(config.phantom);
  else phantom.hu = read_volume(config.ct_path);
  const Volume& hu = phantom.hu;
  fiducials_ = phantom.fiducials;
  std::optional<Volume> mask;
  if (!config.mask_path.empty()) mask = read_volume(config.mask_path);
  surface_ = surface_points(hu, config.iso_hu, 2000);
  if (surface_.empty()) throw_input_error(config.ct_path.empty() ? "phantom" : config.ct_path, "no bone above the iso-value");
  const Eigen::Vector3d centre = mean_point(surface_);
  truth_ = config.truth ? *config.truth : pose_from_rotation_vector(Eigen::Vector3d::Zero(), -centre);

  // Render the X-rays at the truth: every tissue, plus the tool if asked, as log-domain images.
  std::vector<PinholeCamera> cameras;
  for (const auto& [orbit, tilt] : config.views) cameras.push_back(c_arm_view(config.c_arm, orbit, tilt));
  const auto mu = backend_->upload(hu_to_attenuation(config.metal_tool ? with_metal_rod(hu, centre) : hu));
  const auto drrs = backend_->drr(*mu, std::span(&truth_, 1), cameras, DrrParams{0.5, {}});
  std::vector<XrayView> views;
  std::mt19937_64 rng(config.seed);
  for (size_t v = 0; v < cameras.size(); ++v) {
    // The imaging physics acts on the line integrals (each view its own noise), before the
    // log-domain display mapping.
    XrayPhysics physics = config.physics;
    physics.seed = config.seed * 7919u + v;
    const Image drr = physics.any() ? simulate_xray_physics(drrs[v], physics) : drrs[v];
    Image x = drr_to_xray(drr, display_mapping(drr, 1000.0));
    if (config.noise > 0) {
      std::normal_distribution<float> n(0.0f, float(config.noise * 1000.0));
      for (float& p : x.pixels) p += n(rng);
    }
    views.push_back({"view" + std::to_string(v + 1), std::move(x), cameras[v]});
  }
  RegistrationOptions options;
  options.bone_iso_hu = config.iso_hu;
  options.tissue_hu = config.tissue_hu;
  options.correlation_polish = config.correlation_polish;
  options.global_search = config.global_search;
  std::shared_ptr<const PreparedCt> ct;
  if (!config.prepared_path.empty()) {
    PreparedCtSource source{config.ct_path, sha256_of_input(config.ct_path), config.mask_path, "",
                            preparation_settings(options, mask.has_value())};
    if (mask) source.mask_sha256 = sha256_of_input(config.mask_path);
    ct = read_prepared_ct(config.prepared_path, *backend_, source);
  } else {
    ct = std::make_shared<const PreparedCt>(prepare_ct(*backend_, hu, options, mask ? &*mask : nullptr));
  }
  std::vector<std::vector<Eigen::Vector2f>> contours;
  if (config.contours == SweepContours::traced)
    contours = simulated_traced_contours(ct->mesh, views, truth_, options.gpr_edges);
  registration_ = std::make_unique<PreparedRegistration>(*backend_, ct, std::move(views), options, contours);
  preparation_seconds_ = seconds_since(t0);
}

SweepScene::~SweepScene() = default;

SweepRow SweepScene::run(const SweepRun& r) const {
  SweepRow row;
  row.run = r;
  const Pose start = start_pose_at_distance(truth_, surface_, registration_->bone_centre(), r.distance_mm, r.seed);
  row.initial_tre_mm = registration_errors(start, truth_, surface_, {}, {}).surface_tre_mean_mm;
  const RegistrationReport rep = registration_->run(start);
  const RegistrationErrors e = registration_errors(rep.pose, truth_, surface_, fiducials_, registration_->cameras());
  row.final_tre_mm = e.surface_tre_mean_mm;
  row.final_tre_max_mm = e.surface_tre_max_mm;
  row.fiducial_tre_mm = e.fiducial_tre_mean_mm;
  row.mpd_mm = e.mpd_mm;
  row.rotation_deg = e.rotation_deg;
  row.translation_mm = e.translation_mm;
  row.ok = rep.ok;
  row.success = rep.ok && e.surface_tre_mean_mm < 2.0;
  row.confident = rep.confident;
  SweepRow::Confidence& c = row.confidence;
  c.views = int(std::min<size_t>(8, rep.peak_sharpness.views.size()));
  for (int v = 0; v < c.views; ++v) {
    const ViewSharpness& s = rep.peak_sharpness.views[size_t(v)];
    c.correlation[v] = s.correlation;
    c.displaced_correlation[v] = s.displaced_correlation;
    c.simulated_displaced[v] = s.simulated_displaced;
    c.sharpness[v] = s.sharpness;
    c.peak_offset[v] = s.peak_offset;
    if (size_t(v) < rep.expected_view_correlations.size()) c.expected_correlation[v] = rep.expected_view_correlations[size_t(v)];
    for (size_t k = 0; k < 12 && k < s.measured.size(); ++k) {
      c.measured[v][k] = s.measured[k];
      c.simulated[v][k] = s.simulated[k];
    }
  }
  // No views: the run never reached the test (it could not run); its margins stay NaN, unmeasured.
  if (c.views) {
    c.min_sharpness = rep.peak_sharpness.min_sharpness;
    c.max_peak_offset = rep.peak_sharpness.max_peak_offset;
  }
  c.seconds = rep.peak_sharpness.seconds;
  c.sharp = rep.peak_sharpness.sharp;
  c.gpr_pose_sharp = rep.gpr_pose_sharp;
  c.correlation_thresholds_met = rep.correlation_thresholds_met;
  c.correlation_floor = rep.correlation_floor;
  c.expected_correlation_mean = rep.expected_correlation;
  if (!rep.expected_view_correlations.empty() && !rep.view_correlations.empty())
    c.relative_correlation = rep.relative_correlation();
  c.relative_correlation_floor = rep.relative_correlation_floor;
  row.gradient_correlation = rep.gradient_correlation;
  if (!rep.view_correlations.empty())
    row.min_view_correlation = *std::min_element(rep.view_correlations.begin(), rep.view_correlations.end());
  row.seconds = rep.seconds;
  for (const auto& s : rep.stages) {
    (s.name == "coarse" ? row.coarse_seconds : row.fine_seconds) += s.seconds;
    if (s.name != "coarse") row.evaluations += s.evaluations;
  }
  return row;
}

void run_sweep(const SweepScene& scene, const std::vector<SweepRun>& pending,
               const std::function<void(const SweepRow&)>& on_row) {
  std::mutex m;
  // One run per task: runs take 0.1 to 2 s, so dynamic scheduling keeps both cores busy.
  tbb::parallel_for(tbb::blocked_range<size_t>(0, pending.size(), 1), [&](const tbb::blocked_range<size_t>& range) {
    for (size_t i = range.begin(); i != range.end(); ++i) {
      const SweepRow row = scene.run(pending[i]);
      std::lock_guard lock(m);
      on_row(row);
    }
  });
}

namespace {

// The header before the peak-sharpness columns (2026-12-03), and the one before the relative
// correlation's column (2026-12-04): such files are still read.
constexpr const char* kFormerHeader =
    "run,distance_mm,seed,initial_tre_mm,final_tre_mm,final_tre_max_mm,fiducial_tre_mm,mpd_mm,rotation_deg,"
    "translation_mm,success,ok,confident,gradient_correlation,seconds,coarse_seconds,fine_seconds,evaluations,"
    "min_view_correlation";
constexpr size_t kFormerFields = 19, kSharpnessFields = kFormerFields + 2, kFields = kSharpnessFields + 1;

std::string sharpness_header() { return std::string(kFormerHeader) + ",min_sharpness,max_peak_offset"; }

}  // namespace

std::string sweep_csv_header() { return sharpness_header() + ",relative_correlation"; }

std::string sweep_csv_row(const SweepRow& r) {
  std::ostringstream o;
  o << std::setprecision(9) << r.run.index << ',' << r.run.distance_mm << ',' << r.run.seed << ',' << r.initial_tre_mm
    << ',' << r.final_tre_mm << ',' << r.final_tre_max_mm << ',' << r.fiducial_tre_mm << ',' << r.mpd_mm << ','
    << r.rotation_deg << ',' << r.translation_mm << ',' << int(r.success) << ',' << int(r.ok) << ',' << int(r.confident)
    << ',' << r.gradient_correlation << ',' << r.seconds << ',' << r.coarse_seconds << ',' << r.fine_seconds << ','
    << r.evaluations << ',' << r.min_view_correlation << ',' << r.confidence.min_sharpness << ','
    << r.confidence.max_peak_offset << ',' << r.confidence.relative_correlation;
  return o.str();
}

std::vector<SweepRow> read_sweep_csv(const std::string& path) {
  std::ifstream in(path);
  std::vector<SweepRow> rows;
  std::string line;
  if (!in || !std::getline(in, line)) return rows;
  const bool former = line == kFormerHeader, sharpness_only = line == sharpness_header();
  if (!former && !sharpness_only && line != sweep_csv_header())
    throw_input_error(path, "not a sweep CSV (its header is neither this version's nor one of the two earlier ones)");
  const size_t fields = former ? kFormerFields : sharpness_only ? kSharpnessFields : kFields;
  while (std::getline(in, line)) {
    // Every row ends with a newline: a last line without one was cut short, perhaps inside its
    // last field, which would still parse.
    if (in.eof()) break;
    std::istringstream s(line);
    SweepRow r;
    int success = 0, ok = 0, confident = 0;
    std::vector<std::string> f;
    std::string field;
    while (std::getline(s, field, ',')) f.push_back(field);
    if (f.size() != fields) break;  // a line cut short: the sweep stopped while writing it
    try {
      r.run.index = std::stoi(f[0]);
      r.run.distance_mm = std::stod(f[1]);
      r.run.seed = std::stoull(f[2]);
      r.initial_tre_mm = std::stod(f[3]);
      r.final_tre_mm = std::stod(f[4]);
      r.final_tre_max_mm = std::stod(f[5]);
      r.fiducial_tre_mm = std::stod(f[6]);
      r.mpd_mm = std::stod(f[7]);
      r.rotation_deg = std::stod(f[8]);
      r.translation_mm = std::stod(f[9]);
      success = std::stoi(f[10]);
      ok = std::stoi(f[11]);
      confident = std::stoi(f[12]);
      r.gradient_correlation = std::stod(f[13]);
      r.seconds = std::stod(f[14]);
      r.coarse_seconds = std::stod(f[15]);
      r.fine_seconds = std::stod(f[16]);
      r.evaluations = std::stoi(f[17]);
      r.min_view_correlation = std::stod(f[18]);
      // std::stod reads the "nan" and "inf" the writer gives for an unmeasured run and a view
      // without a peak. Former rows keep the defaults: unmeasured.
      if (!former) {
        r.confidence.min_sharpness = std::stod(f[19]);
        r.confidence.max_peak_offset = std::stod(f[20]);
      }
      if (fields == kFields) r.confidence.relative_correlation = std::stod(f[21]);
    } catch (const std::exception&) {
      break;
    }
    r.success = success;
    r.ok = ok;
    r.confident = confident;
    rows.push_back(r);
  }
  return rows;
}

}  // namespace fluoro
