#pragma once
// Robustness sweeps (seed, chapter 2, fig. 7): many registrations of one CT to one set of views,
// from start poses at controlled distances from the truth, each run a row of errors and timings.
// The views are rendered here from the CT at the true pose (optionally with a metal tool that the
// CT lacks, with imaging physics and with noise), so the truth is known exactly.
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "datasets/c_arm.hpp"
#include "datasets/phantom.hpp"
#include "datasets/xray_physics.hpp"
#include "engine/backend.hpp"
#include "pipelines/registration/registration.hpp"

namespace fluoro {

enum class SweepContours {
  automatic,  // the coarse step finds its contours (edges near the projected outline)
  traced,     // edges within 2 px of the true outline: a user's livewire tracing, simulated
};

struct SweepConfig {
  std::string ct_path;                   // a CT file, or (empty) a phantom:
  PhantomParams phantom;
  std::string mask_path;                 // optional bone mask
  std::string prepared_path;             // optional prepared CT file of ct_path (fluoro prepare)
  CArmGeometry c_arm{600, 1000, 384, 0.8};
  std::vector<std::pair<double, double>> views{{0, 0}, {60, 0}, {100, 15}};  // (orbit, tilt), degrees
  std::optional<Pose> truth;             // default: the bone centre at the isocentre
  double from_mm = 1, to_mm = 85, step_mm = 1;
  int runs_per_distance = 50;
  SweepContours contours = SweepContours::traced;
  double noise = 0;                      // Gaussian noise, std as a fraction of the X-ray's range
  bool metal_tool = false;               // a metal rod in the X-rays, absent from the CT
  XrayPhysics physics;                   // scatter, beam hardening, blur, quantum noise (off by default)
  CorrelationPolish correlation_polish = CorrelationPolish::when_needed;  // RegistrationOptions::correlation_polish
  bool global_search = true;             // RegistrationOptions::global_search
  std::string backend = "cpu";
  uint64_t seed = 1;
  double iso_hu = 250;
  double tissue_hu = 100;               // RegistrationOptions::tissue_hu
};

// What a user tracing the bone with a livewire (which snaps to image edges) would give: each
// view's edge pixels within 2 px of the mesh's apparent contour projected at the true pose.
std::vector<std::vector<Eigen::Vector2f>> simulated_traced_contours(const BoneMesh& mesh, const std::vector<XrayView>& views,
                                                                    const Pose& truth, const EdgeDetectionParams& edges);

// Reads SWEEP.json (docs/cli.md). Throws InputError naming the file for a malformed document.
SweepConfig read_sweep_config(const std::string& path);

struct SweepRun {
  int index = 0;
  double distance_mm = 0;  // the requested initial surface TRE
  uint64_t seed = 0;
};

struct SweepRow {
  SweepRun run;
  double initial_tre_mm = 0, final_tre_mm = 0, final_tre_max_mm = 0, fiducial_tre_mm = 0, mpd_mm = 0;
  double rotation_deg = 0, translation_mm = 0;
  bool success = false, ok = false, confident = false;
  double gradient_correlation = 0, seconds = 0, coarse_seconds = 0, fine_seconds = 0;
  int evaluations = 0;
  double min_view_correlation = 0;  // the least gradient correlation of any one view
  // The confidence rule's ingredients (`fluoro sweep --confidence-log`; of them only min_sharpness,
  // max_peak_offset and relative_correlation are in the CSV, NaN when the run measured none). Fixed arrays: rows travel
  // between MPI ranks as bytes. A sweep has at most 8 views.
  struct Confidence {
    int views = 0;
    double correlation[8] = {}, displaced_correlation[8] = {}, simulated_displaced[8] = {}, sharpness[8] = {};
    double measured[8][12] = {}, simulated[8][12] = {};  // per view and displaced pose
    double peak_offset[8] = {};
    double min_sharpness = std::numeric_limits<double>::quiet_NaN();  // NaN: not measured
    double max_peak_offset = std::numeric_limits<double>::quiet_NaN();
    double seconds = 0;
    bool sharp = false;
    bool gpr_pose_sharp = true;  // with the correlation polish: the test at the GPR's pose
    bool correlation_thresholds_met = false;  // the former rule
    double correlation_floor = 0;             // the floor the mean correlation was judged against
    // What a right pose would correlate at the result, per view and on average, the least view's
    // correlation relative to its own, and the floor that was judged against
    // (RegistrationReport::relative_correlation).
    double expected_correlation[8] = {}, expected_correlation_mean = 0;
    double relative_correlation = std::numeric_limits<double>::quiet_NaN();  // NaN: not measured; in the CSV
    double relative_correlation_floor = 0;
  } confidence;
};

// The distance bins of a config (from, from + step, ... up to to) and the most runs a sweep may
// plan (read_sweep_config refuses more; every run is held in memory and numbered with an int).
int64_t sweep_distance_bins(const SweepConfig& config);
constexpr int64_t kMaxSweepRuns = 10'000'000;

// The runs of a config, in order (deterministic); std::invalid_argument beyond kMaxSweepRuns.
std::vector<SweepRun> plan_sweep(const SweepConfig& config);

std::string sweep_csv_header();
std::string sweep_csv_row(const SweepRow& row);
// Parses rows written by sweep_csv_row; a malformed line (say, cut short by a crash) ends the
// list. Files of the two earlier headers (before the min_sharpness and max_peak_offset columns;
// before relative_correlation) are read with the missing ones NaN. Throws InputError naming
// `path` when the header is none of them (another file).
std::vector<SweepRow> read_sweep_csv(const std::string& path);

// The prepared scene: CT, rendered views, surface points, registration.
class SweepScene {
 public:
  explicit SweepScene(const SweepConfig& config);
  ~SweepScene();
  SweepRow run(const SweepRun& r) const;
  double preparation_seconds() const { return preparation_seconds_; }

 private:
  SweepConfig config_;
  std::unique_ptr<Backend> backend_;
  std::unique_ptr<PreparedRegistration> registration_;
  std::vector<Eigen::Vector3d> surface_, fiducials_;
  Pose truth_;
  double preparation_seconds_ = 0;
};

// Runs the runs not yet in `done` in parallel over the cores, calling `on_row` (serialised) for
// each finished row.
void run_sweep(const SweepScene& scene, const std::vector<SweepRun>& pending,
               const std::function<void(const SweepRow&)>& on_row);

// The seed's fig. 7 as SVG: per distance, mean final TRE of the successful runs, cumulative
// failure percentage, and mean time.
std::string sweep_plot_svg(const std::vector<SweepRow>& rows);

}  // namespace fluoro
