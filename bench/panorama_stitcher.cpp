// OpenCV's cv::Stitcher in SCANS mode (affine, the general-purpose tool a user would try first) on
// the goal sets of docs/panorama.md: does it put every frame into one panorama, and how far off is
// the bone length in it. It has no metric scale of its own, so it is handed the one it could at
// best have: the true pixel size in the bone's plane (z_bone / f); its error is then its alignment's
// alone. The landmarks (tantalum beads) are found in its panorama by template matching a patch
// around each bead of the frame where the bead is nearest the centre (as the goal table takes them).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <cstdlib>
#include <string>
#include <opencv2/stitching.hpp>
#include <vector>

#include "bench/panorama_goal_sets.hpp"
#include "engine/field_of_view.hpp"
#include "engine/image_mat.hpp"
#include "pipelines/panorama/panorama.hpp"

namespace fluoro {
namespace {

// 8-bit frames for the stitcher: one grey mapping for all (the 1st-99th percentile of the exposed
// pixels of every frame), so that overlaps look alike; masks: the fields of view (eroded 5 px) so
// that the black surround's circular edge gives no features.
struct StitcherInput {
  std::vector<cv::Mat> frames, grey, colour, masks;
  double lo = 0, hi = 1;  // the grey mapping
};

StitcherInput stitcher_input(const PanoramaScene& s) {
  StitcherInput in;
  std::vector<cv::Mat> frames;
  std::vector<float> exposed;
  for (const auto& im : s.images) {
    cv::Mat f;
    mat_view(im).convertTo(f, CV_32F);
    const cv::Mat mask = field_of_view_mask(f, 5);
    for (int y = 0; y < f.rows; y += 3)
      for (int x = 0; x < f.cols; x += 3)
        if (mask.at<uint8_t>(y, x)) exposed.push_back(f.at<float>(y, x));
    frames.push_back(f);
    in.masks.push_back(mask);
  }
  const double lo = percentile(exposed, 0.01), hi = percentile(exposed, 0.99);
  in.frames = frames, in.lo = lo, in.hi = hi;
  for (const cv::Mat& f : frames) {
    cv::Mat g, c;
    f.convertTo(g, CV_8U, 255.0 / (hi - lo), -lo * 255.0 / (hi - lo));
    cv::cvtColor(g, c, cv::COLOR_GRAY2BGR);
    in.grey.push_back(g);
    in.colour.push_back(c);
  }
  return in;
}

int nearest_centre_frame(const PanoramaScene& s, int k) {
  const Eigen::Vector2d c = 0.5 * Eigen::Vector2d(s.images[0].width - 1, s.images[0].height - 1);
  int best = 0;
  for (int i = 1; i < int(s.images.size()); ++i)
    if ((project_in_frame(s, i, s.landmarks[k]) - c).norm() < (project_in_frame(s, best, s.landmarks[k]) - c).norm()) best = i;
  return best;
}

// Where the patch of `frame` around `px` lies in the panorama (sub-pixel parabola on the NCC peak),
// and the peak's NCC.
std::pair<cv::Point2d, double> locate(const cv::Mat& pano_grey, const cv::Mat& frame, const Eigen::Vector2d& px, int half) {
  const cv::Rect box(int(std::lround(px.x())) - half, int(std::lround(px.y())) - half, 2 * half + 1, 2 * half + 1);
  const cv::Mat patch = frame(box & cv::Rect(0, 0, frame.cols, frame.rows));
  cv::Mat r;
  cv::matchTemplate(pano_grey, patch, r, cv::TM_CCOEFF_NORMED);
  cv::Point best;
  double peak = 0;
  cv::minMaxLoc(r, nullptr, &peak, nullptr, &best);
  auto sub = [&](double a, double b, double c) {
    const double den = a - 2 * b + c;
    return std::abs(den) > 1e-12 ? std::clamp(0.5 * (a - c) / den, -0.5, 0.5) : 0.0;
  };
  double dx = 0, dy = 0;
  if (best.x > 0 && best.x + 1 < r.cols) dx = sub(r.at<float>(best.y, best.x - 1), r.at<float>(best.y, best.x), r.at<float>(best.y, best.x + 1));
  if (best.y > 0 && best.y + 1 < r.rows) dy = sub(r.at<float>(best.y - 1, best.x), r.at<float>(best.y, best.x), r.at<float>(best.y + 1, best.x));
  // The patch's top-left went to `best`: px goes to best + (px - box.tl()).
  const cv::Rect used = box & cv::Rect(0, 0, frame.cols, frame.rows);
  return {cv::Point2d(best.x + dx + px.x() - used.x, best.y + dy + px.y() - used.y), peak};
}

const char* status_name(cv::Stitcher::Status s) {
  switch (s) {
    case cv::Stitcher::OK: return "ok";
    case cv::Stitcher::ERR_NEED_MORE_IMGS: return "need more images";
    case cv::Stitcher::ERR_HOMOGRAPHY_EST_FAIL: return "transform estimation failed";
    case cv::Stitcher::ERR_CAMERA_PARAMS_ADJUST_FAIL: return "adjustment failed";
  }
  return "?";
}

// One table: the stitcher as created (ORB features, confidence threshold 1), or as a user would tune
// it next (SIFT features, matches kept down to confidence 0.3).
void stitcher_table(bool tuned) {
  std::printf("\ncv::Stitcher SCANS, %s:\n\n", tuned ? "SIFT features, panoConfidenceThresh 0.3" : "defaults (ORB, panoConfidenceThresh 1)");
  std::printf("| ruler - bone plane (mm) | seed | frames | status | frames in its panorama | "
              "length error (bone-plane pixel size given) | bead match NCC | time (s) | control: bead NCC in fluoro's bone-plane panorama |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|\n");
  int complete = 0, sets = 0, measured = 0;
  double worst = 0;
  for (const double offset : kGoalRulerOffsetsMm)
    for (const uint32_t seed : kGoalSeeds) {
      ++sets;
      const PanoramaSceneParams params = goal_set_params(offset, seed);
      const PanoramaScene s = make_panorama_scene(params);
      const StitcherInput in = stitcher_input(s);
      // Control for the bead search: the same patches in fluoro's own panorama, realigned to the
      // bone's plane (in the ruler's, parallax misaligns the beads and the max blend hides them).
      double control = -1;
      {
        PlaneContours c;
        c.first = s.contour_first_frame;
        c.polylines[0] = s.contour[0];
        c.polylines[1] = s.contour[1];
        const Panorama ours = align_panorama(in.frames, {}, c);
        if (ours.failure.empty()) {
          cv::Mat grey;
          compose_panorama(in.frames, ours, PanoramaBlend::Max).convertTo(grey, CV_8U, 255.0 / (in.hi - in.lo), -in.lo * 255.0 / (in.hi - in.lo));
          control = 1;
          for (int k = 0; k < 2; ++k) {
            const int f = nearest_centre_frame(s, k);
            control = std::min(control, locate(grey, in.grey[size_t(f)], project_in_frame(s, f, s.landmarks[k]), 24).second);
          }
        }
      }
      cv::Ptr<cv::Stitcher> stitcher = cv::Stitcher::create(cv::Stitcher::SCANS);
      if (tuned) {
        stitcher->setFeaturesFinder(cv::SIFT::create());
        stitcher->setPanoConfidenceThresh(0.3);
      }
      cv::Mat pano;
      const auto t0 = std::chrono::steady_clock::now();
      const cv::Stitcher::Status status = stitcher->stitch(in.colour, in.masks, pano);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      const size_t used = status == cv::Stitcher::OK ? stitcher->component().size() : 0;
      if (status != cv::Stitcher::OK || used != s.images.size()) {
        std::printf("| %+.0f | %u | %d | %s | %zu | - | - | %.2f | %.2f |\n", offset, seed, params.frames, status_name(status), used,
                    seconds, control);
        continue;
      }
      ++complete;
      cv::Mat pano_grey;
      cv::cvtColor(pano, pano_grey, cv::COLOR_BGR2GRAY);
      cv::Point2d q[2];
      double ncc = 1;
      for (int k = 0; k < 2; ++k) {
        const int f = nearest_centre_frame(s, k);
        const auto [p, peak] = locate(pano_grey, in.grey[size_t(f)], project_in_frame(s, f, s.landmarks[k]), 24);
        q[k] = p;
        ncc = std::min(ncc, peak);
      }
      if (std::getenv("STITCHER_SAVE")) cv::imwrite(std::string(std::getenv("STITCHER_SAVE")) + std::to_string(int(offset)) + "_" + std::to_string(seed) + (tuned ? "_sift" : "_orb") + ".png", pano);
      // A bead whose patch does not match anywhere well was not composed recognisably: no length.
      if (ncc < 0.8) {
        std::printf("| %+.0f | %u | %d | ok | %zu | beads not found in its panorama | %.2f | %.2f | %.2f |\n", offset, seed, params.frames,
                    used, ncc, seconds, control);
        continue;
      }
      const double length = cv::norm(q[1] - q[0]) * s.bone_plane_mm / s.focal_px;
      const double error = 100 * (length - s.true_length_mm) / s.true_length_mm;
      ++measured;
      worst = std::max(worst, std::abs(error));
      std::printf("| %+.0f | %u | %d | ok | %zu | %+.2f %% | %.2f | %.2f | %.2f |\n", offset, seed, params.frames, used, error, ncc,
                  seconds, control);
    }
  std::printf("\n%d of %d sets with every frame in one panorama; %d with both beads found in it; worst length error there: %.2f %%\n",
              complete, sets, measured, worst);
}

}  // namespace

int run_stitcher_comparison() {
  stitcher_table(false);
  stitcher_table(true);
  return 0;
}

}  // namespace fluoro
