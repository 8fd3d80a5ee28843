#pragma once
// CT to fluoroscopic X-ray registration, the seed's three funnelling steps (chapter 2, section V):
// an initial pose (given, or from landmarks: landmarks.hpp), coarse 2D/3D ICP of the X-rays' bone
// contours against the CT bone mesh's apparent contour, and fine gradient projection
// registration (GPR) in stages from a smooth, coarse gradient field to a sharp one.
//
//   PreparedRegistration reg(backend, ct_hu, views);   // mesh, gradient fields, edge pixels: once
//   RegistrationReport r = reg.run(initial_pose);       // per start pose; thread-safe
//
// Preparation is the expensive part that depends only on the CT and the X-rays, so a sweep over
// thousands of start poses pays for it once; its CT-only part (prepared_ct.hpp) can be prepared
// before the X-rays exist and saved (`fluoro prepare`).
#include <algorithm>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "engine/backend.hpp"
#include "pipelines/registration/bone_mesh.hpp"
#include "pipelines/registration/contour_icp.hpp"
#include "pipelines/registration/correlation_polish.hpp"
#include "pipelines/registration/edge_pixels.hpp"
#include "pipelines/registration/global_search.hpp"
#include "pipelines/registration/gpr_registration.hpp"
#include "pipelines/registration/gradient_correlation.hpp"
#include "pipelines/registration/peak_sharpness.hpp"
#include "pipelines/registration/prepared_ct.hpp"
#include "pipelines/registration/simplex.hpp"

namespace fluoro {

// One X-ray: its image in the log domain (bone dark; see read_xray) and its calibrated camera.
struct XrayView {
  std::string name;  // for messages: usually the image file
  Image image;
  PinholeCamera camera;
};

// One step of the fine registration: a gradient field of the given smoothness, sampled by rays
// through a subset of edge pixels, maximised by batched quasi-Newton steps or the downhill simplex.
struct GprStage {
  double sigma_mm = 1.0;              // Gaussian scale of the gradient field
  double grid_mm = 1.0;               // the field is resampled to at least this spacing (0: CT grid)
  double step_mm = 1.0;               // ray sampling step
  int max_pixels = 2000;              // edge pixels per view (0: all)
  double rotation_step_deg = 2.0;     // initial simplex; the quasi-Newton's scale
  double translation_step_mm = 2.0;
  // Tolerances of either optimiser; max_iterations is the simplex's (the quasi-Newton's is
  // QuasiNewtonOptions::max_iterations).
  SimplexOptions simplex{200, 1e-4, 0.05};
  // > 0: the field's voxels weaker than this fraction of its strongest are zeroed
  // (Op::gradient_floor), so rays skip bone interiors; docs/benchmarks.md, issue 13.
  double gradient_floor = 0.0;
  // The optimiser (gpr_registration.hpp). The simplex by default: batched quasi-Newton steps in
  // stages 2 and 3 cost 3 to 10 % less CPU per sweep and registered the femur phantom more
  // accurately, but the pelvis phantom less (docs/benchmarks.md, "Fewer score evaluations"); in
  // stage 1 they lost a 20 mm start that the simplex's wide first simplex kept.
  FineOptimiser optimiser = FineOptimiser::simplex;
};

// When the correlation polish runs (RegistrationOptions::correlation_polish).
enum class CorrelationPolish {
  off,
  always,
  // After the confidence check at the GPR's pose, when that pose is a sharp peak in every view
  // (else the result is doubtful however polished) and either the X-rays depart from the DRR model
  // (polish_below_relative_correlation) or the peak lies further from the pose than the check
  // allows. Otherwise that check is the result's, and the run costs what it did without the polish.
  when_needed,
};
// "off", "on", "auto" (the command line's and SWEEP.json's words).
const char* correlation_polish_name(CorrelationPolish mode);
std::optional<CorrelationPolish> correlation_polish_from_name(const std::string& name);

struct RegistrationOptions {
  double mu_water_per_mm = 0.02;
  // Bone: the mesh's iso-value (the coarse step's surface). A mask replaces it.
  double bone_iso_hu = 250.0;
  // The fine step's gradient field keeps only attenuation in excess of soft tissue's, so that
  // edges between fat, muscle and air (which move with the patient) do not count, while every
  // bone edge keeps its full profile, cancellous bone (150 to 300 HU) included. A threshold at
  // the mesh's iso-value instead shifts the modelled edges into the bone: on simulated views
  // it left the pelvis 0.35 mm off against 0.22 mm (docs/registration.md). A mask replaces it.
  double tissue_hu = 100.0;
  BoneMeshParams mesh;
  bool coarse = true;  // run the contour ICP step
  ContourIcpOptions icp;
  // Coarse restarts: while the fit's gradient correlation is under coarse_good_correlation,
  // restart ICP from the start turned by up to coarse_restart_deg and shifted by
  // up to coarse_restart_mm.
  int coarse_restarts = 8;
  double coarse_restart_deg = 25.0, coarse_restart_mm = 20.0;
  // Edges that serve as automatic contours (coarse step) and as GPR edge pixels (fine step).
  EdgeDetectionParams contour_edges{0.05, 0.15, 2.0, 0};
  EdgeDetectionParams gpr_edges{0.05, 0.15, 1.0, 0};
  std::vector<GprStage> stages{
      {2.0, 2.0, 2.0, 500, 3.0, 3.0, {120, 1e-3, 0.2}},
      {1.0, 1.0, 1.0, 600, 1.0, 1.0, {150, 1e-4, 0.1}},
      // The polish: every edge pixel (up to 4,000 per view, which noisy X-rays exceed), from close
      // by, on the sharpest field. A small subset's optimum sits a few tenths of a millimetre off
      // the full set's, depending on which pixels it holds; a smoother field's edges sit inside
      // curved bone outlines (femur: 0.31 mm with sigma 1 mm, 0.24 with 0.5).
      {0.5, 1.0, 1.0, 4000, 0.3, 0.3, {25, 1e-4, 0.05}},
  };
  // After the GPR stages, a last stage maximising the gradient correlation (correlation_polish.hpp):
  // under imaging physics the DRR lacks (scatter, beam hardening, detector blur) the GPR score's
  // optimum is a plateau; the correlation's is not (docs/registration.md, "Robustness to imaging
  // physics"). It adds up to three measurements like the confidence check's (7 poses' bone DRRs
  // each with translations_by_warp; 40 to 85 % of a pelvis CT registration's CPU time and about
  // double a femur phantom's when they rendered 13, docs/registration.md), so by default it runs
  // only where it is needed (CorrelationPolish::when_needed): `fluoro register
  // --polish-correlation=on|off|auto`, SWEEP.json's "correlation_polish".
  CorrelationPolish correlation_polish = CorrelationPolish::when_needed;
  // when_needed polishes when a view of the GPR's pose correlates under this fraction of what an
  // X-ray of the whole CT would there (RegistrationReport::relative_correlation): the X-rays depart
  // from the DRR model. Least views at 10 mm starts (docs/registration.md, section 4): DRRs of the
  // CT itself 0.992 to 0.998 over four anatomies; 1 px of detector blur or 20,000 photons alone
  // 0.975 to 0.985, scatter (SPR 0.25) 0.90 to 0.92, all four effects 0.71 to 0.79.
  double polish_below_relative_correlation = 0.99;
  CorrelationPolishOptions correlation_polish_options;
  int final_restarts = 0;       // fresh optimiser runs from the last stage's optimum
  double max_angle_deg = 30.0;  // GPR direction test (outliers: tools, other anatomy)
  // The former confidence rule (reported as RegistrationReport::correlation_thresholds_met; it
  // decides only with require_correlation_thresholds, below): the gradient correlation of the
  // X-rays with bone DRRs at the final pose, averaged over the views, reaches this. On simulated
  // views it is 0.5 to 0.67 when registered and under 0.15 several mm off; but wrong poses that
  // fit two views of three reach 0.46. The coarse step also uses it (a fit correlating this well
  // replaces the start).
  double min_gradient_correlation = 0.35;
  // ... and every view's correlation reaches this (with the defaults this implies the mean
  // threshold). A pose that is right fits every view; the wrong poses that fit well on
  // average (a femur 6 to 15 mm off after a start 37 mm or more away) leave one view at 0.33 or
  // less, where registered views of the femur and of the pelvis with metal and noise correlate
  // 0.38 or more: margins of 0.02 and 0.03. Both values are corrected for the X-ray's white noise
  // (gradient_correlation.hpp), so they do not fall with the dose.
  double min_view_correlation = 0.35;
  // `confident` is decided by the peak-sharpness test (peak_sharpness.hpp): every view's
  // correlation drops around the result as much, relative to its level, as the CT's own DRR
  // predicts for a right pose. The two thresholds above are absolute levels calibrated on the
  // femur phantom's DRRs; they fail both ways on other anatomy and imaging (docs/registration.md,
  // "Confidence"), so they are reported (RegistrationReport::correlation_thresholds_met) but only
  // decide when require_correlation_thresholds is set, and then together with the sharpness.
  PeakSharpnessOptions peak_sharpness;
  bool require_correlation_thresholds = false;
  // An optional floor under the mean correlation at the result (0: off, the default): a result
  // correlating less is not confident, however sharp. For imaging a user knows: on the 650
  // successes logged for it (four anatomies, clean and under imaging physics, 128^3 phantoms and the
  // 3 mm pelvis CT with 384^2-512^2 views) right poses correlated 0.466 or more (0.436 in later
  // pelvis-CT runs at scatter SPR 1), and a wrong pose that the sharpness test refused only by its
  // largest peak offset (0.403 against 0.4) correlated 0.22 (docs/registration.md, "A near miss on
  // the femur"); but a registration of a 64^3 femur phantom (4 mm voxels) in three 256^2 views,
  // sharp in every view, correlated 0.26: the level depends on the resolution, so no fixed floor is
  // the default. Noise-corrected like the thresholds above.
  double min_confident_correlation = 0.0;
  // A floor under every view's correlation relative to what a right pose would reach there at
  // the result (RegistrationReport::relative_correlation): transfers across CTs and resolutions
  // where the absolute floor above does not (docs/registration.md, "A floor relative to the CT's
  // own correlation"). 0 or less: off.
  double min_relative_correlation = 0.45;
  // The coarse step restarts while its fit correlates less than this (it only has to come
  // within the fine steps' reach).
  double coarse_good_correlation = 0.2;
  // When the contour ICP from the start correlates under coarse_good_correlation, a global search
  // (global_search.hpp: rotations about the bone centre, each view's shift by FFT correlation)
  // proposes poses; the ICP runs from the global_search_starts best-correlating of them before
  // the random restarts. Starts whose ICP fit correlates that well never pay for it, nor do
  // starts the fine stages reach on their own (fine_before_search).
  bool global_search = true;
  GlobalSearchOptions global_search_options;
  int global_search_starts = 3;
  // A start near enough for the ICP's fit to correlate 0.2 skips the search, but that fit can be
  // a wrong one (the pelvis CT from 20 mm: 0.206, ending far off); so can a first fine stage's
  // result that looked registered (fine_before_search). When the registration from the start
  // ends not confident without a search, it runs again with the search, and the confident (else
  // the better correlating) of the two results is reported. Confident runs never pay for it.
  bool global_search_when_doubtful = true;
  // After the search, the first fine stage also runs from the global_search_starts best proposals
  // themselves, not only from the ICP fit that correlates best.
  bool fine_from_proposals = true;
  // Before searching, the first fine stage runs from the coarse step's main start (the ICP fit,
  // or the start when the fit correlates worse), and the search, with the ICP's restarts, is
  // skipped when its result correlates like a registered pose (min_gradient_correlation on
  // average and min_view_correlation in every view), or correlates so on average and is a sharp
  // peak in every view (peak_sharpness's min_axis_sharpness, the peak within the smaller of its
  // displacements; not with require_correlation_thresholds): imaging physics holds views under
  // the fixed threshold (beam hardening: the pelvis CT's worst view correlates 0.31 at the
  // truth), and under the first rule alone every run that reached the check searched. On the
  // pelvis CT the contour ICP correlates under 0.2 from every start 10 mm or more away, but the
  // fine stages converge from up to about 15 mm, where the search cost two thirds of a run
  // (docs/registration.md, "Far starts"). When
  // the search runs after all, that result competes with the ones from its starts, so a start
  // that needs the search pays at most one first-stage run more (none when the search leaves the
  // fit as it was). Only with global_search_when_doubtful, whose retry runs a wrongly skipped search.
  bool fine_before_search = true;
  // A start whose correlation is under this is lost (far off, nothing of the bone in place): a
  // coarse fit that correlates better replaces it instead of competing with it.
  double coarse_lost_correlation = 0.05;
  // Gaussian smoothing before differentiating, in pixels of the views reduced to about 256 a side;
  // a view reduced further for a coarse CT (below) is smoothed as much in mm, so fewer pixels.
  double correlation_blur_px = 1.0;
  // The correlation's views are reduced further while a reduced pixel at the views' isocentre
  // still resolves the CT's finest voxel spacing into at least this many pixels
  // (reduced_view.hpp, correlation_reductions). 0: the size alone decides.
  double correlation_pixels_per_voxel = 2.5;
};

struct StageReport {
  std::string name;  // "coarse", "fine 1", ...
  double seconds = 0;
  int iterations = 0;
  int evaluations = 0;  // pose evaluations (GPR) or pairs (coarse)
  double value = 0;     // GPR score (fine) or inlier RMS ray distance in mm (coarse)
  bool converged = false;
  Pose pose;  // T_world_ct at the end of the step
};

struct RegistrationReport {
  Pose initial, pose;           // T_world_ct
  bool ok = true;               // false: the registration could not run to the end
  std::string failure_reason;
  double score = 0;             // GPR score of the last stage at `pose`
  double gradient_correlation = 0;  // of the X-rays with bone DRRs at `pose`, mean over views
  std::vector<double> view_correlations;  // the same, per view
  // Every stage ran and the result is a sharp maximum of the correlation in every view
  // (peak_sharpness, and gpr_pose_sharp), every view correlates at least min_relative_correlation
  // of its expected correlation (relative_correlation_floor_met), and the mean at least
  // min_confident_correlation when that floor is set (with require_correlation_thresholds also
  // the thresholds).
  bool confident = false;
  PeakSharpness peak_sharpness;  // at `pose`
  // With the correlation polish: the GPR stages' pose before it reaches the required sharpness
  // too (the polish makes a wrong pose a maximum of the mean correlation: femur, a pose 19.5 mm
  // off reached sharpness 0.450 against the required 0.45; docs/registration.md). Its peak
  // offset is not judged (the GPR's plateau under imaging physics). True without the polish.
  bool gpr_pose_sharp = true;
  // The former rule: the mean and every view's correlation reach their thresholds, at the result
  // and at the GPR stages' pose before the correlation polish (on which they were calibrated).
  bool correlation_thresholds_met = false;
  double correlation_floor = 0;  // RegistrationOptions::min_confident_correlation, as judged (0: off)
  // The mean correlation reaches the floor, or no floor is set (0 or less, or NaN: off).
  bool correlation_floor_met() const { return !(correlation_floor > 0) || gradient_correlation >= correlation_floor; }
  // Per view, the correlation a right pose would reach at `pose` with an X-ray of the whole CT
  // (PreparedRegistration::expected_view_correlations), and their mean; empty and 0 when the
  // result was not measured (the registration did not run to the end).
  std::vector<double> expected_view_correlations;
  double expected_correlation = 0;
  // Per view, its correlation over its expected one: about 1 at a right pose in clean X-rays of
  // the CT (whatever the anatomy and resolution), less where the X-ray holds what the CT lacks
  // (scatter, noise, tools), much less in a view that a wrong pose fits poorly. An expectation
  // under kLeastExpectedCorrelation (a view that hardly sees bone) counts as that much, so that a
  // near-zero denominator cannot pass any correlation.
  static constexpr double kLeastExpectedCorrelation = 0.05;
  static std::vector<double> relative_view_correlations(const std::vector<double>& correlations,
                                                        const std::vector<double>& expected) {
    std::vector<double> out;
    for (size_t v = 0; v < correlations.size() && v < expected.size(); ++v)
      out.push_back(correlations[v] / std::max(expected[v], kLeastExpectedCorrelation));
    return out;
  }
  std::vector<double> relative_view_correlations() const {
    return relative_view_correlations(view_correlations, expected_view_correlations);
  }
  // The least of them (the view a compromise of views fits worst), 0 when none was measured.
  double relative_correlation() const {
    const std::vector<double> r = relative_view_correlations();
    return r.empty() ? 0.0 : *std::min_element(r.begin(), r.end());
  }
  double relative_correlation_floor = 0;  // RegistrationOptions::min_relative_correlation, as judged (0: off)
  bool relative_correlation_floor_met() const {
    return !(relative_correlation_floor > 0) || relative_correlation() >= relative_correlation_floor;
  }
  std::vector<StageReport> stages;
  // The global search ran (in the coarse step, from a far start or a doubtful result's retry).
  bool global_search_ran = false;
  // A doubtful first result was retried with the search (global_search_when_doubtful): the first
  // attempt's stages are listed before the retry's, named "first attempt: ...", and the result is
  // the retry's when result_from_retry.
  bool retried_when_doubtful = false;
  bool result_from_retry = false;
  double seconds = 0;
};

class PreparedRegistration {
 public:
  // `hu` is the CT in HU; `mask` (optional, non-zero = bone, any geometry overlapping the CT)
  // replaces the iso-value. `contours` (optional): per view, user-traced bone contour pixels;
  // views without them (or all, when empty) get automatic contours. Throws InputError for
  // inconsistent input: no views, an image whose size differs from its camera's, an X-ray with
  // no edges, a CT without bone.
  PreparedRegistration(Backend& backend, const Volume& hu, std::vector<XrayView> views,
                       const RegistrationOptions& options = {}, const Volume* mask = nullptr,
                       const std::vector<std::vector<Eigen::Vector2f>>& contours = {});
  // The same from a CT prepared beforehand (prepare_ct, or a prepared file): on `backend`, with
  // `options` whose preparation_settings() it was prepared with.
  PreparedRegistration(Backend& backend, std::shared_ptr<const PreparedCt> ct, std::vector<XrayView> views,
                       const RegistrationOptions& options = {},
                       const std::vector<std::vector<Eigen::Vector2f>>& contours = {});
  ~PreparedRegistration();

  RegistrationReport run(const Pose& initial) const;

  const BoneMesh& mesh() const { return ct_->mesh; }
  const std::shared_ptr<const PreparedCt>& prepared_ct() const { return ct_; }
  const std::vector<XrayView>& views() const { return views_; }
  const std::vector<PinholeCamera>& cameras() const { return cameras_; }
  // The gradient correlation's reduced views (RegistrationOptions::correlation_pixels_per_voxel).
  const std::vector<PinholeCamera>& correlation_cameras() const { return correlation_cameras_; }
  // ... and each one's blur before differentiating, in its reduced pixels.
  double correlation_blur_px(size_t view) const { return correlation_xrays_.at(view).blur_px(); }
  // The finest stage's gradient field (for overlays) and the bone centre rotations turn about.
  const DeviceVolume& fine_gradient() const { return *stages_.back().gradient; }
  const Eigen::Vector3d& bone_centre() const { return centre_; }
  Backend& backend() const { return backend_; }
  double preparation_seconds() const { return preparation_seconds_; }
  // Gradient correlation (-1 to 1) of the X-rays with bone DRRs at `pose`: per view, and the
  // mean over the views.
  std::vector<double> view_gradient_correlations(const Pose& pose) const;
  double gradient_correlation(const Pose& pose) const;
  // The mean over the views, for each of several poses (one backend batch).
  std::vector<double> gradient_correlations(std::span<const Pose> poses) const;
  // The peak-sharpness test at `pose` (peak_sharpness.hpp): one batch of 7 poses' bone DRRs (the
  // pose and its six rotations; the six translations warped from the pose's, translated_drr.hpp).
  // With `expected`, also each view's expected correlation there (expected_view_correlations).
  PeakSharpness measure_peak_sharpness(const Pose& pose, std::vector<double>* expected = nullptr) const;
  // The same with other displacements (the correlation polish's stencils).
  PeakSharpness measure_peak_sharpness(const Pose& pose, const PeakSharpnessOptions& o,
                                       std::vector<double>* expected = nullptr) const;
  // Per view, the gradient correlation that an X-ray of the whole CT at `pose` (a DRR of bone and
  // non-bone attenuation, noise-free) has with the bone DRR there: what a right pose scores at
  // these views' geometry and resolution when the X-ray holds nothing the CT lacks.
  // `bone_drrs`: the bone DRRs at `pose` when already rendered (one per view), else rendered here.
  std::vector<double> expected_view_correlations(const Pose& pose, const std::vector<Image>* bone_drrs = nullptr) const;

 private:
  // expected_view_correlations from the bone DRRs at `pose` (one per view) and, when known, their
  // derivatives (XrayGradients::derivatives with the correlation's blur).
  std::vector<double> expected_view_correlations(const Pose& pose, const std::vector<Image>& bone,
                                                 const std::vector<XrayGradients::Derivatives>* bone_derivatives) const;
  // The gradient correlation per pose and view (one backend batch of bone DRRs).
  std::vector<std::vector<double>> per_view_correlations(std::span<const Pose> poses) const;
  // Everything but the CT's part: edge pixels, contours, the gradient correlation's reduced views.
  void prepare(std::shared_ptr<const PreparedCt> ct, const std::vector<std::vector<Eigen::Vector2f>>& contours);
  // The coarse step's best-correlating contour-ICP fit so far, with its gradient correlation and
  // the start's, and the work it took.
  struct CoarseFit {
    ContourIcpResult fit;
    double correlation = 0, start_correlation = 0;
    int evaluations = 0, iterations = 0;
  };
  CoarseFit icp_from_start(const Pose& initial) const;
  // Widens a poor fit: with `search`, the global search's proposals (the ICP from the
  // global_search_starts best, which are appended to *proposals), then the restarts while it
  // still correlates under coarse_good_correlation.
  void widen_coarse_fit(const Pose& initial, bool search, CoarseFit& best, std::vector<Pose>* proposals) const;
  // The first fine stage's starts after the coarse step, the main one first: the fit, the start
  // when the fit does not settle it, and the proposals (fine_from_proposals).
  std::vector<Pose> first_fine_starts(const Pose& initial, const CoarseFit& c, const std::vector<Pose>& proposals) const;
  // One registration from `initial` (run() makes one or two).
  RegistrationReport attempt(const Pose& initial, bool force_search) const;
  // Fine stage i from `start`.
  GprRegistrationResult run_stage(size_t i, const Pose& start) const;
  struct Stage {
    GprStage params;
    std::shared_ptr<const DeviceVolume> gradient;
    std::vector<EdgePixels> edges;
  };
  Backend& backend_;
  RegistrationOptions options_;
  std::vector<XrayView> views_;
  std::vector<PinholeCamera> cameras_;
  std::shared_ptr<const PreparedCt> ct_;
  Eigen::Vector3d centre_;
  std::vector<ContourData> user_contours_, auto_contours_;
  std::vector<Stage> stages_;
  std::vector<PinholeCamera> correlation_cameras_;  // reduced views for the gradient correlation
  std::vector<XrayGradients> correlation_xrays_;    // their X-rays' derivatives, reduced
  std::vector<EdgePixels> all_edges_;  // every GPR edge pixel
  std::optional<GlobalSearch> global_search_;
  double preparation_seconds_ = 0;
};

}  // namespace fluoro
