#include "pipelines/registration/registration.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <random>

#include <opencv2/imgproc.hpp>

#include "engine/attenuation.hpp"
#include "engine/error.hpp"
#include "pipelines/registration/apparent_contour.hpp"
#include "pipelines/registration/gpr_registration.hpp"
#include "pipelines/registration/nearest_point_map.hpp"

namespace fluoro {
namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Attenuation of bone only: the CT's mu where the mask (looked up at each voxel's physical
// position, nearest voxel) is non-zero, or where HU reaches the iso-value.
Volume bone_attenuation(const Volume& hu, const Volume* mask, const RegistrationOptions& o) {
  if (!mask) return hu_to_attenuation(hu, {o.mu_water_per_mm, o.bone_iso_hu});
  Volume mu = hu_to_attenuation(hu, {o.mu_water_per_mm});
  const VolumeGeometry& g = hu.geometry;
  const VolumeGeometry& m = mask->geometry;
  for (int k = 0; k < g.size.z(); ++k)
    for (int j = 0; j < g.size.y(); ++j)
      for (int i = 0; i < g.size.x(); ++i) {
        const Eigen::Vector3d idx = m.physical_to_index(g.index_to_physical(Eigen::Vector3d(i, j, k)));
        const Eigen::Vector3i n(int(std::lround(idx.x())), int(std::lround(idx.y())), int(std::lround(idx.z())));
        const bool in = (n.array() >= 0).all() && (n.array() < m.size.array()).all() && mask->at(n.x(), n.y(), n.z()) != 0;
        if (!in) mu.at(i, j, k) = 0;
      }
  return mu;
}

}  // namespace

PreparedRegistration::PreparedRegistration(Backend& backend, const Volume& hu, std::vector<XrayView> views,
                                           const RegistrationOptions& options, const Volume* mask,
                                           const std::vector<std::vector<Eigen::Vector2f>>& contours)
    : backend_(backend), options_(options), views_(std::move(views)) {
  const auto t0 = std::chrono::steady_clock::now();
  if (views_.empty()) throw InputError("registration: no X-ray views");
  if (options_.stages.empty()) throw std::invalid_argument("registration: no fine stages");
  if (!contours.empty() && contours.size() != views_.size())
    throw InputError("contours: " + std::to_string(contours.size()) + " views of contours for " +
                     std::to_string(views_.size()) + " X-rays");
  for (const XrayView& v : views_) {
    validate_camera(v.camera, v.name);
    if (v.image.width != v.camera.width || v.image.height != v.camera.height)
      throw_input_error(v.name, "the image is " + std::to_string(v.image.width) + "x" + std::to_string(v.image.height) +
                                    " pixels but its camera says " + std::to_string(v.camera.width) + "x" +
                                    std::to_string(v.camera.height));
    cameras_.push_back(v.camera);
  }
  mesh_ = mask ? bone_mesh_from_mask(*mask, options_.mesh, "mask")
               : bone_mesh_from_iso(hu, options_.bone_iso_hu, options_.mesh, "CT");
  centre_ = mesh_.centroid();

  // Edge pixels: every one for the agreement check; subsets per stage.
  for (const XrayView& v : views_) {
    all_edges_.push_back(detect_edge_pixels(v.image, XrayPolarity::log_domain, options_.gpr_edges, v.name));
    edge_maps_.emplace_back(all_edges_.back().pixels, v.camera.width, v.camera.height);
    const EdgePixels c = detect_edge_pixels(v.image, XrayPolarity::log_domain, options_.contour_edges, v.name);
    auto_contours_.push_back({v.camera, c.pixels, c.directions, ContourMatching::mesh_to_contour});
  }
  for (size_t v = 0; v < contours.size(); ++v)
    if (!contours[v].empty()) user_contours_.push_back({views_[v].camera, contours[v], {}, ContourMatching::contour_to_mesh});
    else user_contours_.push_back(auto_contours_[v]);

  const auto mu = backend_.upload(bone_attenuation(hu, mask, options_));
  const double finest = hu.geometry.spacing.minCoeff();
  for (const GprStage& s : options_.stages) {
    Stage stage{s, {}, {}};
    stage.gradient = backend_.gradient_field(*mu, {s.sigma_mm, s.grid_mm > finest * 1.01 ? s.grid_mm : 0.0});
    for (const EdgePixels& e : all_edges_) stage.edges.push_back(evenly_spread(e, s.max_pixels));
    stages_.push_back(std::move(stage));
  }
  preparation_seconds_ = seconds_since(t0);
}

PreparedRegistration::~PreparedRegistration() = default;

double PreparedRegistration::agreement(const Pose& pose) const {
  // The bone's projected outline, the boundary of its silhouette: it always shows as an edge in
  // an X-ray (bone against soft tissue), unlike the inner folds of the apparent contour.
  size_t total = 0, found = 0;
  for (size_t v = 0; v < views_.size(); ++v) {
    const PinholeCamera& cam = cameras_[v];
    cv::Mat silhouette(cam.height, cam.width, CV_8U, cv::Scalar(0));
    std::vector<cv::Point> projected(mesh_.vertices.size());
    bool visible = true;
    for (size_t i = 0; i < mesh_.vertices.size() && visible; ++i) {
      const Eigen::Vector2d uv = cam.project(pose * mesh_.vertices[i]);
      visible = uv.allFinite() && std::abs(uv.x()) < 1e6 && std::abs(uv.y()) < 1e6;
      if (visible) projected[i] = cv::Point(int(std::lround(uv.x())), int(std::lround(uv.y())));
    }
    if (!visible) continue;  // the bone reaches behind the source: no outline to compare
    for (const auto& t : mesh_.triangles) {
      const cv::Point tri[3] = {projected[size_t(t[0])], projected[size_t(t[1])], projected[size_t(t[2])]};
      cv::fillConvexPoly(silhouette, tri, 3, cv::Scalar(255));
    }
    const NearestPointMap& edges = edge_maps_[v];
    for (int y = 1; y + 1 < cam.height; ++y) {
      const uint8_t* row = silhouette.ptr<uint8_t>(y);
      for (int x = 1; x + 1 < cam.width; ++x) {
        if (!row[x] || (row[x - 1] && row[x + 1] && silhouette.at<uint8_t>(y - 1, x) && silhouette.at<uint8_t>(y + 1, x)))
          continue;
        ++total;
        const int k = edges.nearest(x, y);
        if (k >= 0 && (all_edges_[v].pixels[size_t(k)] - Eigen::Vector2f(float(x), float(y))).norm() <=
                          float(options_.agreement_px))
          ++found;
      }
    }
  }
  return total ? double(found) / double(total) : 0.0;
}

ContourIcpResult PreparedRegistration::coarse_register(const Pose& initial) const {
  const auto& contours = user_contours_.empty() ? auto_contours_ : user_contours_;
  ContourIcpResult best = register_contours(mesh_, contours, initial, options_.icp);
  // ICP stalls in local minima from distant starts, where the predicted outline then misses the
  // X-rays' edges. Restart from rotations and shifts of the start about the bone centre (a fixed,
  // reproducible sequence) until the outline agrees, keeping the best-agreeing fit.
  double best_agreement = agreement(best.pose);
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d c = initial * centre_;
  int evaluations = best.pairs, iterations = best.iterations;
  for (int i = 0; i < options_.coarse_restarts && best_agreement < options_.min_agreement; ++i) {
    const Eigen::Vector3d w = Eigen::Vector3d(u(rng), u(rng), u(rng)) * (options_.coarse_restart_deg * std::numbers::pi / 180);
    const Eigen::Vector3d t = Eigen::Vector3d(u(rng), u(rng), u(rng)) * options_.coarse_restart_mm;
    Pose delta = pose_from_rotation_vector(w, Eigen::Vector3d::Zero());
    delta.translation() = c + t - delta.linear() * c;
    const ContourIcpResult r = register_contours(mesh_, contours, delta * initial, options_.icp);
    evaluations += r.pairs;
    iterations += r.iterations;
    const double a = agreement(r.pose);
    if (a > best_agreement) {
      best = r;
      best_agreement = a;
    }
  }
  best.pairs = evaluations;
  best.iterations = iterations;
  return best;
}

RegistrationReport PreparedRegistration::run(const Pose& initial) const {
  const auto t_all = std::chrono::steady_clock::now();
  RegistrationReport report;
  report.initial = report.pose = initial;
  try {
    if (options_.coarse) {
      const auto t0 = std::chrono::steady_clock::now();
      const ContourIcpResult c = coarse_register(report.pose);
      // The coarse step can lose its way from a distant start (its nearest-edge pairs are then
      // mostly wrong); keep its result only where the first fine stage's own measure, the GPR
      // score, agrees that it is an improvement.
      const Stage& first = stages_.front();
      const Pose candidates[] = {report.pose, c.pose};
      GprParams gp;
      gp.projection.step_mm = first.params.step_mm;
      gp.max_angle_deg = options_.max_angle_deg;
      const std::vector<double> s = backend_.gpr_score(*first.gradient, candidates, cameras_, first.edges, gp);
      if (s[1] >= s[0]) report.pose = c.pose;
      report.stages.push_back({"coarse", seconds_since(t0), c.iterations, c.pairs, c.rms_mm, c.converged, c.pose});
    }
    for (size_t i = 0; i < stages_.size(); ++i) {
      const Stage& s = stages_[i];
      const auto t0 = std::chrono::steady_clock::now();
      GprRegistrationOptions o;
      o.gpr.projection.step_mm = s.params.step_mm;
      o.gpr.max_angle_deg = options_.max_angle_deg;
      o.rotation_step_deg = s.params.rotation_step_deg;
      o.translation_step_mm = s.params.translation_step_mm;
      o.simplex = s.params.simplex;
      o.restarts = i + 1 == stages_.size() ? 1 : 0;
      const GprRegistrationResult g = register_gpr(backend_, *s.gradient, cameras_, s.edges, report.pose, centre_, o);
      report.pose = g.pose;
      report.score = g.score;
      report.stages.push_back({"fine " + std::to_string(i + 1), seconds_since(t0), g.iterations, g.evaluations, g.score,
                               g.converged, g.pose});
    }
    report.agreement = agreement(report.pose);
    report.confident = report.agreement >= options_.min_agreement;
  } catch (const InputError& e) {
    report.ok = false;
    report.confident = false;
    report.failure_reason = e.what();
  }
  report.seconds = seconds_since(t_all);
  return report;
}

}  // namespace fluoro
