#include "pipelines/registration/registration.hpp"

#include <algorithm>
#include <chrono>
#include <exception>
#include <cmath>
#include <numbers>
#include <numeric>
#include <optional>
#include <random>

#include <opencv2/imgproc.hpp>
#include <tbb/parallel_for.h>

#include "engine/error.hpp"
#include "engine/image_mat.hpp"
#include "engine/random_draws.hpp"
#include "pipelines/registration/apparent_contour.hpp"
#include "pipelines/registration/gpr_registration.hpp"
#include "pipelines/registration/gradient_correlation.hpp"
#include "pipelines/registration/global_search.hpp"
#include "pipelines/registration/nearest_point_map.hpp"
#include "pipelines/registration/reduced_view.hpp"
#include "pipelines/registration/translated_drr.hpp"

namespace fluoro {
namespace {

// The views' mean (of per-view gradient correlations).
double mean_of(const std::vector<double>& per_view) {
  return std::accumulate(per_view.begin(), per_view.end(), 0.0) / double(per_view.size());
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Each view's correlation at the pose a check measured.
std::vector<double> view_correlations_of(const PeakSharpness& p) {
  std::vector<double> out;
  for (const ViewSharpness& v : p.views) out.push_back(v.correlation);
  return out;
}

// CorrelationPolish::when_needed (registration.hpp), from the confidence check at the GPR's pose
// and each view's expected correlation there.
bool polish_needed(const PeakSharpness& at_gpr, const std::vector<double>& expected, const RegistrationOptions& o) {
  if (at_gpr.views.empty() || at_gpr.min_sharpness < o.peak_sharpness.min_axis_sharpness) return false;
  if (at_gpr.max_peak_offset > o.peak_sharpness.max_peak_offset) return true;
  const std::vector<double> relative =
      RegistrationReport::relative_view_correlations(view_correlations_of(at_gpr), expected);
  return std::any_of(relative.begin(), relative.end(),
                     [&](double r) { return !(r >= o.polish_below_relative_correlation); });
}

}  // namespace

PreparedRegistration::PreparedRegistration(Backend& backend, const Volume& hu, std::vector<XrayView> views,
                                           const RegistrationOptions& options, const Volume* mask,
                                           const std::vector<std::vector<Eigen::Vector2f>>& contours)
    : backend_(backend), options_(options), views_(std::move(views)) {
  // The cheap checks before the CT's costly preparation.
  if (views_.empty()) throw InputError("registration: no X-ray views");
  prepare(std::make_shared<const PreparedCt>(prepare_ct(backend, hu, options, mask)), contours);
}

PreparedRegistration::PreparedRegistration(Backend& backend, std::shared_ptr<const PreparedCt> ct,
                                           std::vector<XrayView> views, const RegistrationOptions& options,
                                           const std::vector<std::vector<Eigen::Vector2f>>& contours)
    : backend_(backend), options_(options), views_(std::move(views)) {
  prepare(std::move(ct), contours);
}

void PreparedRegistration::prepare(std::shared_ptr<const PreparedCt> ct,
                                   const std::vector<std::vector<Eigen::Vector2f>>& contours) {
  const auto t0 = std::chrono::steady_clock::now();
  ct_ = std::move(ct);
  if (views_.empty()) throw InputError("registration: no X-ray views");
  if (options_.stages.empty()) throw std::invalid_argument("registration: no fine stages");
  if (!ct_ || ct_->gradients.size() != options_.stages.size() || !ct_->bone_mu || !ct_->non_bone_mu)
    throw std::invalid_argument("registration: the prepared CT does not match the options' fine stages");
  std::vector<const DeviceVolume*> volumes{ct_->bone_mu.get(), ct_->non_bone_mu.get()};
  for (const auto& g : ct_->gradients) volumes.push_back(g.get());
  for (const DeviceVolume* v : volumes)
    if (v->owner() != &backend_) throw std::invalid_argument("registration: the prepared CT is on another backend");
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
  centre_ = ct_->mesh.centroid();

  // Edge pixels: all of them, and subsets per stage.
  // The views in parallel (each detection is mostly serial); one noise measurement per view.
  all_edges_.resize(views_.size());
  std::vector<EdgePixels> contour_edges(views_.size());
  std::vector<std::exception_ptr> errors(views_.size());
  tbb::parallel_for(size_t(0), views_.size(), [&](size_t i) {
    try {
      const XrayView& v = views_[i];
      if (v.image.empty()) throw_input_error(v.name, "empty image");
      const double noise = noise_ratio(mat_view(v.image));
      all_edges_[i] = detect_edge_pixels(v.image, XrayPolarity::log_domain, options_.gpr_edges, v.name, noise);
      contour_edges[i] = detect_edge_pixels(v.image, XrayPolarity::log_domain, options_.contour_edges, v.name, noise);
    } catch (...) {
      errors[i] = std::current_exception();
    }
  });
  for (const std::exception_ptr& e : errors)  // the first view's error first, as in a serial loop
    if (e) std::rethrow_exception(e);
  for (size_t i = 0; i < views_.size(); ++i)
    auto_contours_.push_back({views_[i].camera, contour_edges[i].pixels, contour_edges[i].directions, ContourMatching::mesh_to_contour});
  for (size_t v = 0; v < contours.size(); ++v)
    if (!contours[v].empty()) user_contours_.push_back({views_[v].camera, contours[v], {}, ContourMatching::contour_to_mesh});
    else user_contours_.push_back(auto_contours_[v]);

  // The gradient correlation's reduced views: about 256 pixels a side, fewer for a coarse CT.
  const int correlation_side = 256;
  const std::vector<int> factors = correlation_reductions(cameras_, ct_->bone_mu->geometry().spacing.minCoeff(),
                                                          correlation_side, options_.correlation_pixels_per_voxel, 96);
  for (size_t v = 0; v < views_.size(); ++v) {
    const int by_size = size_reduction(views_[v].camera, correlation_side);
    const int factor = factors[v];
    ReducedView r = reduce_view_by(views_[v].camera, views_[v].image, factor);
    correlation_cameras_.push_back(r.camera);
    correlation_xrays_.emplace_back(r.image, options_.correlation_blur_px * by_size / factor);
  }
  if (options_.coarse && options_.global_search) {
    std::vector<Image> images;
    for (const XrayView& v : views_) images.push_back(v.image);
    global_search_.emplace(cameras_, images, options_.global_search_options, ct_->bone_mu->geometry().spacing.minCoeff());
  }
  for (size_t i = 0; i < options_.stages.size(); ++i) {
    Stage stage{options_.stages[i], ct_->gradients[i], {}};
    for (const EdgePixels& e : all_edges_)
      stage.edges.push_back(tile_ordered(evenly_spread(e, stage.params.max_pixels)));
    stages_.push_back(std::move(stage));
  }
  // The CT's part counts too, whether computed here or loaded from a prepared file.
  preparation_seconds_ = ct_->seconds + seconds_since(t0);
}

PreparedRegistration::~PreparedRegistration() = default;

std::vector<std::vector<double>> PreparedRegistration::per_view_correlations(std::span<const Pose> poses) const {
  // Penney et al.'s gradient correlation of X-ray and bone DRR, per view, corrected for the
  // X-ray's noise (gradient_correlation.hpp). Soft tissue, absent from the bone DRR, lowers it a
  // little everywhere; a wrong pose lowers it a lot.
  // At most about 256 pixels a side: the measure needs the bone's shape, not fine detail.
  const std::vector<Image> drrs = backend_.drr(*ct_->bone_mu, poses, correlation_cameras_, DrrParams{1.5, {}});
  const size_t views = views_.size();
  std::vector<std::vector<double>> out(poses.size(), std::vector<double>(views, 0.0));
  for (size_t p = 0; p < poses.size(); ++p)
    for (size_t v = 0; v < views; ++v) {
      const Image& d = drrs[p * views + v];
      out[p][v] = correlation_xrays_[v].correlate(mat_view(d));
    }
  return out;
}

std::vector<double> PreparedRegistration::expected_view_correlations(const Pose& pose,
                                                                     const std::vector<Image>* bone_drrs) const {
  if (bone_drrs) return expected_view_correlations(pose, *bone_drrs, nullptr);
  return expected_view_correlations(
      pose, backend_.drr(*ct_->bone_mu, std::span<const Pose>(&pose, 1), correlation_cameras_, DrrParams{1.5, {}}), nullptr);
}

std::vector<double> PreparedRegistration::expected_view_correlations(
    const Pose& pose, const std::vector<Image>& bone, const std::vector<XrayGradients::Derivatives>* bone_derivatives) const {
  const std::span<const Pose> at(&pose, 1);
  // The non-bone attenuation is smooth but for the bone's outline and the skin: a 3 mm step moved
  // the expected correlations by under 0.001 (1.5 mm before; docs/benchmarks.md, "Direct sums").
  const std::vector<Image> rest = backend_.drr(*ct_->non_bone_mu, at, correlation_cameras_, DrrParams{3.0, {}});
  std::vector<double> out;
  for (size_t v = 0; v < views_.size(); ++v) {
    // Line integrals add: bone plus the rest is the whole CT's DRR, log domain, so bone dark as an
    // X-ray's once negated. Noise-free: no noise correction.
    const cv::Mat whole = mat_view(bone[v]) + mat_view(rest[v]);
    const XrayGradients whole_xray(-whole, correlation_xrays_[v].blur_px(), false);
    out.push_back(bone_derivatives ? whole_xray.correlate((*bone_derivatives)[v]) : whole_xray.correlate(mat_view(bone[v])));
  }
  return out;
}

PeakSharpness PreparedRegistration::measure_peak_sharpness(const Pose& pose, std::vector<double>* expected) const {
  return measure_peak_sharpness(pose, options_.peak_sharpness, expected);
}

PeakSharpness PreparedRegistration::measure_peak_sharpness(const Pose& pose, const PeakSharpnessOptions& o,
                                                           std::vector<double>* expected) const {
  const auto t0 = std::chrono::steady_clock::now();
  const Eigen::Vector3d centre_world = pose * centre_;
  const std::vector<Pose> displaced = displaced_poses(pose, centre_world, o);  // the rotations, then the translations
  // Rendered: the result, its rotations, and its translations unless they are warped.
  const size_t rendered_displaced = o.translations_by_warp ? kDisplacedRotations : displaced.size();
  std::vector<Pose> poses{pose};
  poses.insert(poses.end(), displaced.begin(), displaced.begin() + std::ptrdiff_t(rendered_displaced));
  const std::vector<Image> drrs = backend_.drr(*ct_->bone_mu, poses, correlation_cameras_, DrrParams{1.5, {}});
  const size_t views = views_.size();
  std::vector<ViewSharpness> per_view;
  std::vector<XrayGradients::Derivatives> at_result_derivatives;  // per view, of the DRR at the pose
  for (size_t v = 0; v < views; ++v) {
    // The bone DRR at the result stands in for an X-ray of a right pose (bone dark, as X-rays are;
    // noise-free, so no noise correction). Each displaced DRR's derivatives serve both comparisons.
    const cv::Mat at_result = mat_view(drrs[v]);
    at_result_derivatives.push_back(correlation_xrays_[v].derivatives(at_result));
    const XrayGradients simulated_xray = correlation_xrays_[v].drr_as_xray(at_result_derivatives.back());
    std::vector<double> measured, simulated;
    for (size_t k = 0; k < displaced.size(); ++k) {
      const cv::Mat d = k < rendered_displaced
                            ? mat_view(drrs[(k + 1) * views + v])
                            : translated_drr(at_result, correlation_cameras_[v], centre_world,
                                             displaced[k].translation() - pose.translation());
      const XrayGradients::Derivatives g = correlation_xrays_[v].derivatives(d);
      measured.push_back(correlation_xrays_[v].correlate(g));
      simulated.push_back(simulated_xray.correlate(g));
    }
    const double c0 = correlation_xrays_[v].correlate(at_result_derivatives.back());
    per_view.push_back(view_sharpness(c0, measured, simulated, o));
  }
  if (expected) {
    const std::vector<Image> at_pose(drrs.begin(), drrs.begin() + std::ptrdiff_t(views));
    *expected = expected_view_correlations(pose, at_pose, &at_result_derivatives);
  }
  PeakSharpness out = judge_peak_sharpness(std::move(per_view), o);
  out.evaluations = int(poses.size());
  out.seconds = seconds_since(t0);
  return out;
}

std::vector<double> PreparedRegistration::view_gradient_correlations(const Pose& pose) const {
  return per_view_correlations(std::span(&pose, 1))[0];
}

double PreparedRegistration::gradient_correlation(const Pose& pose) const {
  return mean_of(view_gradient_correlations(pose));
}

std::vector<double> PreparedRegistration::gradient_correlations(std::span<const Pose> poses) const {
  std::vector<double> out;
  for (const std::vector<double>& views : per_view_correlations(poses)) out.push_back(mean_of(views));
  return out;
}

PreparedRegistration::CoarseFit PreparedRegistration::icp_from_start(const Pose& initial) const {
  const auto& contours = user_contours_.empty() ? auto_contours_ : user_contours_;
  CoarseFit c;
  c.fit = register_contours(ct_->mesh, contours, initial, options_.icp);
  const std::vector<double> g = gradient_correlations(std::vector<Pose>{c.fit.pose, initial});
  c.correlation = g[0];
  c.start_correlation = g[1];
  c.evaluations = c.fit.pairs;
  c.iterations = c.fit.iterations;
  return c;
}

void PreparedRegistration::widen_coarse_fit(const Pose& initial, bool search, CoarseFit& best,
                                            std::vector<Pose>* proposals) const {
  const auto& contours = user_contours_.empty() ? auto_contours_ : user_contours_;
  // ICP stalls in local minima from distant starts, where the bone DRR then correlates poorly
  // with the X-rays. ICP from another start; its fit replaces the best when it correlates better.
  auto icp_from = [&](const Pose& start) {
    const ContourIcpResult r = register_contours(ct_->mesh, contours, start, options_.icp);
    best.evaluations += r.pairs;
    best.iterations += r.iterations;
    const double g = gradient_correlation(r.pose);
    if (g > best.correlation) {
      best.fit = r;
      best.correlation = g;
    }
  };
  // From far off, a global search first (global_search.hpp): ICP from its best poses, by the
  // gradient correlation.
  if (search) {
    std::vector<Pose> found;
    for (const GlobalHypothesis& h : global_search_->search(backend_, *ct_->bone_mu, initial, centre_))
      found.push_back(h.pose);
    const std::vector<double> g = gradient_correlations(found);
    std::vector<size_t> order(found.size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return g[a] > g[b]; });
    for (size_t i = 0; i < order.size() && int(i) < options_.global_search_starts; ++i) {
      icp_from(found[order[i]]);
      proposals->push_back(found[order[i]]);
    }
  }
  // Then restarts from rotations and shifts of the start about the bone centre (a fixed,
  // reproducible sequence) until it correlates, keeping the best-correlating fit.
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d c = initial * centre_;
  for (int i = 0; i < options_.coarse_restarts && best.correlation < options_.coarse_good_correlation; ++i) {
    const Eigen::Vector3d w = draw3(u, rng) * (options_.coarse_restart_deg * std::numbers::pi / 180);
    const Eigen::Vector3d t = draw3(u, rng) * options_.coarse_restart_mm;
    Pose delta = pose_from_rotation_vector(w, Eigen::Vector3d::Zero());
    delta.translation() = c + t - delta.linear() * c;
    icp_from(delta * initial);
  }
}

std::vector<Pose> PreparedRegistration::first_fine_starts(const Pose& initial, const CoarseFit& c,
                                                          const std::vector<Pose>& proposals) const {
  // The coarse step can lose its way (from a distant start, or in a cluttered image where its
  // nearest-edge pairs are mostly wrong), and a better correlation does not prove a better
  // pose: on the pelvis a fit correlating 0.22 against the start's 0.10 led 3 mm astray,
  // where the start led to 0.5 mm. So a fit that correlates better than the start goes on
  // to the first fine stage together with the start, which tells them apart. Only a fit that
  // correlates as well as a registered pose should (min_gradient_correlation), or one that
  // beats a start too far off to correlate at all (coarse_lost_correlation), replaces the
  // start outright. A fit that correlates worse than the start is dropped.
  // After a global search the proposals themselves follow: on the pelvis CT the contour ICP from
  // a right proposal can leave it, in the clutter of soft tissue, table and the other hip, where
  // the fine stage would converge.
  std::vector<Pose> starts;
  if (c.correlation >= c.start_correlation) {
    starts.push_back(c.fit.pose);
    if (!(c.start_correlation < options_.coarse_lost_correlation || c.correlation >= options_.min_gradient_correlation))
      starts.push_back(initial);
  } else {
    starts.push_back(initial);
  }
  if (options_.fine_from_proposals) starts.insert(starts.end(), proposals.begin(), proposals.end());
  return starts;
}

GprRegistrationResult PreparedRegistration::run_stage(size_t i, const Pose& start) const {
  const Stage& s = stages_[i];
  GprRegistrationOptions o;
  o.gpr.projection.step_mm = s.params.step_mm;
  o.gpr.max_angle_deg = options_.max_angle_deg;
  o.rotation_step_deg = s.params.rotation_step_deg;
  o.translation_step_mm = s.params.translation_step_mm;
  o.simplex = s.params.simplex;
  o.simplex.speculative = backend_.prefers_batches();
  o.optimiser = s.params.optimiser;
  o.restarts = i + 1 == stages_.size() ? options_.final_restarts : 0;
  return register_gpr(backend_, *s.gradient, cameras_, s.edges, start, centre_, o);
}

RegistrationReport PreparedRegistration::run(const Pose& initial) const {
  const auto t_all = std::chrono::steady_clock::now();
  RegistrationReport first = attempt(initial, false);
  if (!first.ok || first.confident || first.global_search_ran || !global_search_ || !options_.global_search_when_doubtful)
    return first;
  RegistrationReport again = attempt(initial, true);
  // The first is not confident here: the retry wins when it is, or when it correlates better.
  const bool take_again = again.ok && (again.confident || again.gradient_correlation > first.gradient_correlation);
  RegistrationReport& out = take_again ? again : first;
  std::vector<StageReport> stages;
  for (StageReport s : first.stages) {
    s.name = "first attempt: " + s.name;
    stages.push_back(std::move(s));
  }
  stages.insert(stages.end(), again.stages.begin(), again.stages.end());
  RegistrationReport result = std::move(out);
  result.stages = std::move(stages);
  result.global_search_ran = true;
  result.retried_when_doubtful = true;
  result.result_from_retry = take_again;
  result.seconds = seconds_since(t_all);
  return result;
}

RegistrationReport PreparedRegistration::attempt(const Pose& initial, bool force_search) const {
  const auto t_all = std::chrono::steady_clock::now();
  RegistrationReport report;
  report.initial = report.pose = initial;
  report.correlation_floor = options_.min_confident_correlation;
  report.relative_correlation_floor = options_.min_relative_correlation;
  try {
    // The first fine stage runs from the starts the coarse step leaves (first_fine_starts; before
    // a search, from the main one alone); each result is judged by its gradient correlation and
    // the first best goes on.
    std::vector<Pose> starts{initial};
    std::vector<GprRegistrationResult> firsts;             // firsts[i] from starts[i]
    std::vector<std::vector<double>> first_views;          // their per-view correlations, once judged
    std::vector<double> first_correlations;                // and the means over the views
    double fine_seconds = 0;
    // Runs it from the starts not yet run (`from` only ever extends the starts already run),
    // judges the results when `judge` (one batch), and returns the index of the first best (0
    // while unjudged).
    auto run_first_stage = [&](const std::vector<Pose>& from, bool judge) {
      const auto t0 = std::chrono::steady_clock::now();
      for (size_t i = firsts.size(); i < from.size(); ++i) firsts.push_back(run_stage(0, from[i]));
      if (judge) {
        std::vector<Pose> ends;
        for (size_t i = first_correlations.size(); i < firsts.size(); ++i) ends.push_back(firsts[i].pose);
        for (std::vector<double>& views : per_view_correlations(ends)) {
          first_correlations.push_back(mean_of(views));
          first_views.push_back(std::move(views));
        }
      }
      fine_seconds += seconds_since(t0);
      return size_t(std::max_element(first_correlations.begin(), first_correlations.end()) - first_correlations.begin());
    };
    // Correlates like a registered pose, on average and in every view (the former confidence
    // rule's thresholds, RegistrationOptions::min_gradient_correlation).
    auto like_registered = [this](const std::vector<double>& views) {
      return mean_of(views) >= options_.min_gradient_correlation &&
             *std::min_element(views.begin(), views.end()) >= options_.min_view_correlation;
    };
    // The first fine stage's result i is near enough that the search can be skipped: it correlates
    // like a registered pose, or, where imaging physics holds a view's correlation under that fixed
    // threshold (beam hardening: the pelvis CT's worst view correlates 0.31 at the truth), it
    // correlates so on average and is, in every view, as sharp a peak as the confidence check
    // asks of a result, with the peak within the smaller displacement of that check (not within
    // the result's 0.4 mm: one fine stage leaves the pose up to about a millimetre off). A skipped
    // search's result is judged by the unchanged confidence check, and a doubtful one is retried
    // with the search forced. Not when the thresholds decide confidence: a view under them makes
    // the result doubtful anyway, and the skip would only add the retry.
    auto near_enough_to_skip_search = [&](size_t i) {
      const std::vector<double>& views = first_views[i];
      if (like_registered(views)) return true;
      if (mean_of(views) < options_.min_gradient_correlation || options_.require_correlation_thresholds) return false;
      const PeakSharpness p = measure_peak_sharpness(firsts[i].pose);
      fine_seconds += p.seconds;
      const PeakSharpnessOptions& o = options_.peak_sharpness;
      return p.min_sharpness >= o.min_axis_sharpness && p.max_peak_offset <= std::min(o.rotation_deg, o.translation_mm);
    };
    if (options_.coarse) {
      auto t0 = std::chrono::steady_clock::now();
      CoarseFit c = icp_from_start(initial);
      std::vector<Pose> proposals;
      const bool search = global_search_ && (force_search || c.correlation < options_.coarse_good_correlation);
      // Only where a wrongly skipped search is made good by the retry of a doubtful result.
      const bool fine_first = search && !force_search && options_.fine_before_search &&
                              options_.global_search_when_doubtful && !stages_.empty();
      if (!fine_first) widen_coarse_fit(initial, search, c, &proposals);
      starts = first_fine_starts(initial, c, proposals);
      // Before a search, the first fine stage from the main start alone. The start's run beside
      // the fit guards against a fit that correlates better and leads astray; a result that
      // correlates like a registered pose settles that as it would settle a fit (first_fine_starts),
      // and if none does the search runs and the start's run is made then. On the pelvis CT the
      // ICP fit and the start correlate alike (the fit barely moves) and converge alike.
      if (fine_first) starts.resize(1);
      double coarse_seconds = seconds_since(t0);
      bool searched = search && !fine_first;
      if (fine_first && !near_enough_to_skip_search(run_first_stage(starts, true))) {
        // Not near enough after all: search, and run the first stage from the starts it adds (the
        // fit may change as well); the results so far compete with theirs.
        t0 = std::chrono::steady_clock::now();
        widen_coarse_fit(initial, true, c, &proposals);
        std::vector<Pose> more = first_fine_starts(initial, c, proposals);
        more.erase(std::remove_if(more.begin(), more.end(),
                                  [&](const Pose& p) {
                                    return std::any_of(starts.begin(), starts.end(),
                                                       [&](const Pose& q) { return p.matrix() == q.matrix(); });
                                  }),
                   more.end());
        starts.insert(starts.end(), more.begin(), more.end());
        coarse_seconds += seconds_since(t0);
        searched = true;
      }
      report.global_search_ran = searched;
      const bool better = c.correlation >= c.start_correlation;
      report.pose = better ? c.fit.pose : initial;
      report.stages.push_back({"coarse", coarse_seconds, c.iterations, c.evaluations, c.fit.rms_mm,
                               c.fit.converged && better, report.pose});
    }
    for (size_t i = 0; i < stages_.size(); ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      GprRegistrationResult g;
      if (i == 0) {
        // A single start needs no judging.
        g = firsts[run_first_stage(starts, starts.size() > 1)];
        g.evaluations = g.iterations = 0;
        for (const GprRegistrationResult& r : firsts) {
          g.evaluations += r.evaluations;
          g.iterations += r.iterations;
        }
      } else {
        g = run_stage(i, report.pose);
      }
      report.pose = g.pose;
      report.score = g.score;
      const double seconds = i == 0 ? fine_seconds : seconds_since(t0);
      report.stages.push_back({"fine " + std::to_string(i + 1), seconds, g.iterations, g.evaluations, g.score,
                               g.converged, g.pose});
    }
    // The thresholds were calibrated on the GPR's results. The last stage maximises the very
    // correlation they judge, and raises a wrong pose's as well (femur, a 40 mm start: a pose
    // 18 mm off at 0.27 ended 4.7 mm off at 0.41, its worst view at 0.30), so the GPR's pose
    // must pass them too.
    bool gpr_pose_passes = true;
    std::optional<PeakSharpness> at_result;  // the result's confidence check, once measured
    // when_needed: the check at the GPR's pose comes first, and decides whether to polish.
    bool polish = options_.correlation_polish == CorrelationPolish::always;
    std::optional<PeakSharpness> at_gpr;
    std::vector<double> expected_at_gpr;
    const Pose gpr_pose_before_polish = report.pose;
    if (options_.correlation_polish == CorrelationPolish::when_needed) {
      at_gpr = measure_peak_sharpness(report.pose, &expected_at_gpr);
      polish = polish_needed(*at_gpr, expected_at_gpr, options_);
    }
    if (polish) {
      const auto t0 = std::chrono::steady_clock::now();
      // The peak-sharpness thresholds were measured on the GPR's results; the polish maximises the
      // very correlation they judge, for a wrong pose too, so the GPR's pose must be as sharp as
      // well. Its peak offset is not judged: under imaging physics the GPR stops anywhere on a
      // plateau 0.5 to 1 mm wide (docs/registration.md), which is what the polish corrects. The
      // polish starts from this measurement.
      const bool checked_already = at_gpr.has_value();  // when_needed
      PeakSharpness before = checked_already ? std::move(*at_gpr) : measure_peak_sharpness(report.pose);
      at_gpr.reset();
      // The stage's time includes that check's, also when it was measured before the stage.
      const double measured_earlier = checked_already ? before.seconds : 0.0;
      gpr_pose_passes = like_registered(view_correlations_of(before));
      report.gpr_pose_sharp = !before.views.empty() && before.min_sharpness >= options_.peak_sharpness.min_axis_sharpness;
      CorrelationPolishResult c = polish_by_correlation(
          [this](const Pose& p, const PeakSharpnessOptions& o) { return measure_peak_sharpness(p, o); }, report.pose,
          std::move(before), centre_, options_.correlation_polish_options);
      report.pose = c.pose;
      at_result = std::move(c.at_pose);
      // The report's GPR score is of the final pose (the last GPR stage's settings).
      const Stage& last = stages_.back();
      GprParams gpr;
      gpr.projection.step_mm = last.params.step_mm;
      gpr.max_angle_deg = options_.max_angle_deg;
      report.score = backend_.gpr_score(*last.gradient, std::span(&report.pose, 1), cameras_, last.edges, gpr)[0];
      report.stages.push_back({"correlation", measured_earlier + seconds_since(t0), c.steps, c.evaluations, c.correlation, c.converged,
                               report.pose});
    }
    // The sharpness test renders the result too (the polish did already): its correlations are the report's.
    if (at_result) {
      report.peak_sharpness = std::move(*at_result);
      // A polish that took no step ends at the GPR's pose, whose expectation when_needed measured.
      report.expected_view_correlations =
          !expected_at_gpr.empty() && report.pose.matrix() == gpr_pose_before_polish.matrix()
              ? std::move(expected_at_gpr)
              : expected_view_correlations(report.pose);
    } else if (at_gpr) {
      report.peak_sharpness = std::move(*at_gpr);
      report.expected_view_correlations = std::move(expected_at_gpr);
    } else {
      report.peak_sharpness = measure_peak_sharpness(report.pose, &report.expected_view_correlations);
    }
    report.expected_correlation = mean_of(report.expected_view_correlations);
    report.view_correlations = view_correlations_of(report.peak_sharpness);
    report.gradient_correlation = mean_of(report.view_correlations);
    report.correlation_thresholds_met = gpr_pose_passes && like_registered(report.view_correlations);
    report.confident = report.peak_sharpness.sharp && report.gpr_pose_sharp &&
                       report.correlation_floor_met() && report.relative_correlation_floor_met() &&
                       (!options_.require_correlation_thresholds || report.correlation_thresholds_met);
  } catch (const InputError& e) {
    report.ok = false;
    report.confident = false;
    report.failure_reason = e.what();
  }
  report.seconds = seconds_since(t_all);
  return report;
}

const char* correlation_polish_name(CorrelationPolish mode) {
  switch (mode) {
    case CorrelationPolish::off: return "off";
    case CorrelationPolish::always: return "on";
    case CorrelationPolish::when_needed: return "auto";
  }
  return "auto";
}

std::optional<CorrelationPolish> correlation_polish_from_name(const std::string& name) {
  for (CorrelationPolish m : {CorrelationPolish::off, CorrelationPolish::always, CorrelationPolish::when_needed})
    if (name == correlation_polish_name(m)) return m;
  return std::nullopt;
}

}  // namespace fluoro
