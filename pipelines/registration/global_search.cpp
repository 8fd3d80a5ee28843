#include "pipelines/registration/global_search.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>
#include <tbb/parallel_for.h>

#include "engine/image_mat.hpp"
#include "pipelines/registration/reduced_view.hpp"

namespace fluoro {
namespace {

// The x and y derivatives of the smoothed image times `sign`, zero-mean, scaled together to unit
// norm (so the correlation of two of them is a cosine in [-1, 1]), each in the top-left corner of a
// zero canvas of `padded` size, then transformed (OpenCV's packed real DFT). All zero when flat.
void derivative_spectra(const cv::Mat& image, double blur_px, double sign, cv::Size padded, cv::Mat out[2]) {
  cv::Mat smooth;
  cv::GaussianBlur(image, smooth, cv::Size(), blur_px);
  cv::Mat d[2];
  cv::Sobel(smooth, d[0], CV_32F, 1, 0, 1, sign * 0.5);  // central differences
  cv::Sobel(smooth, d[1], CV_32F, 0, 1, 1, sign * 0.5);
  double norm2 = 0;
  for (cv::Mat& a : d) {
    a -= cv::mean(a)[0];
    norm2 += a.dot(a);
  }
  const double scale = norm2 > 0 ? 1.0 / std::sqrt(norm2) : 0.0;
  for (int a = 0; a < 2; ++a) {
    cv::Mat canvas = cv::Mat::zeros(padded, CV_32F);
    d[a].convertTo(canvas(cv::Rect(0, 0, image.cols, image.rows)), CV_32F, scale);
    cv::dft(canvas, out[a]);
  }
}

// The circular correlation surface r(s) = sum_p x(p + s) d(p) read at a real-valued shift, bilinearly.
double read_shift(const cv::Mat& r, double sx, double sy) {
  const int w = r.cols, h = r.rows;
  const double fx = std::floor(sx), fy = std::floor(sy);
  const double ax = sx - fx, ay = sy - fy;
  auto at = [&](int x, int y) { return double(r.at<float>(((y % h) + h) % h, ((x % w) + w) % w)); };
  const int x0 = int(fx), y0 = int(fy);
  return (1 - ay) * ((1 - ax) * at(x0, y0) + ax * at(x0 + 1, y0)) + ay * ((1 - ax) * at(x0, y0 + 1) + ax * at(x0 + 1, y0 + 1));
}

// The rotation vectors (radians) (i, j, k) * step_deg, i, j, k in [-n, n], within max_deg of no
// rotation, the zero one first: the search's grid.
std::vector<Eigen::Vector3d> rotation_grid(double step_deg, int n, double max_deg) {
  std::vector<Eigen::Vector3d> out{Eigen::Vector3d::Zero()};
  for (int i = -n; i <= n; ++i)
    for (int j = -n; j <= n; ++j)
      for (int k = -n; k <= n; ++k) {
        const Eigen::Vector3d w = Eigen::Vector3d(i, j, k) * step_deg;
        if ((i || j || k) && w.norm() <= max_deg + 1e-9) out.push_back(w * std::numbers::pi / 180);
      }
  return out;
}

// Best first.
bool by_score(const GlobalHypothesis& a, const GlobalHypothesis& b) { return a.score > b.score; }

// `pose` turned by the rotation vector `w` (radians) about its bone centre (`centre_ct` mapped by it).
Pose turned_about_centre(const Pose& pose, const Eigen::Vector3d& centre_ct, const Eigen::Vector3d& w) {
  const Eigen::Vector3d centre = pose * centre_ct;
  Pose delta = pose_from_rotation_vector(w, Eigen::Vector3d::Zero());
  delta.translation() = centre - delta.linear() * centre;
  return delta * pose;
}

}  // namespace

double parabola_vertex(double minus, double zero, double plus) {
  const double bend = minus + plus - 2 * zero;
  if (bend < 0) return std::clamp(0.5 * (minus - plus) / bend, -1.0, 1.0);
  if (std::max(minus, plus) > zero) return plus > minus ? 1.0 : -1.0;
  return 0.0;
}

GlobalSearch::Scale GlobalSearch::make_scale(std::span<const PinholeCamera> cameras, std::span<const Image> xrays,
                                              std::span<const int> factors, const GlobalSearchOptions& options) {
  Scale scale;
  int width = 0, height = 0;
  std::vector<ReducedView> reduced;
  for (size_t v = 0; v < cameras.size(); ++v) {
    reduced.push_back(reduce_view_by(cameras[v], xrays[v], factors[v]));
    width = std::max(width, reduced.back().camera.width);
    height = std::max(height, reduced.back().camera.height);
  }
  // Padding by the largest shift searched keeps the circular correlation from wrapping into it.
  scale.max_shift = int(std::ceil(options.max_shift_fraction * std::max(width, height)));
  scale.padded = cv::Size(cv::getOptimalDFTSize(width + scale.max_shift + 1), cv::getOptimalDFTSize(height + scale.max_shift + 1));
  for (ReducedView& r : reduced) {
    View view;
    view.camera = r.camera;
    derivative_spectra(r.image, options.blur_px, -1.0, scale.padded, view.spectrum);  // X-rays: bone dark
    scale.views.push_back(std::move(view));
  }
  return scale;
}

GlobalSearch::GlobalSearch(std::span<const PinholeCamera> cameras, std::span<const Image> xrays, GlobalSearchOptions options,
                           double voxel_mm)
    : options_(options) {
  const std::vector<PinholeCamera> all(cameras.begin(), cameras.end());
  std::vector<int> by_size;
  for (const PinholeCamera& c : cameras) by_size.push_back(size_reduction(c, options_.max_side));
  scale_ = make_scale(cameras, xrays, by_size, options_);
  // The grid scores 123 rotations, the refinement at most 64 (after the grid's best 8 are scored
  // again): the grid's pixels need only resolve the CT's voxels (docs/benchmarks.md, "The search's
  // grid by the CT's voxels").
  grid_factors_ = correlation_reductions(all, voxel_mm, options_.max_side, options_.grid_pixels_per_voxel, 48);
  if (grid_factors_ != by_size) grid_ = make_scale(cameras, xrays, grid_factors_, options_);
}

std::vector<Eigen::Vector3d> GlobalSearch::rotations() const {
  const double step = options_.rotation_step_deg, limit = options_.max_rotation_deg;
  return rotation_grid(step, step > 0 ? int(std::floor(limit / step + 1e-9)) : 0, limit);
}

std::vector<GlobalHypothesis> GlobalSearch::search(Backend& backend, const DeviceVolume& bone_mu, const Pose& initial,
                                                   const Eigen::Vector3d& centre_ct) const {
  std::vector<GlobalHypothesis> out =
      score_rotations(grid_scale(), backend, bone_mu, std::span(&initial, 1), centre_ct, rotations());
  std::stable_sort(out.begin(), out.end(), by_score);
  if (grid_) {
    // Scores at the grid's coarser size do not compare with the refinement's: the best few (as many
    // as are returned or refined) are scored again at the refinement's size, each about its own
    // centre, and the rest dropped.
    size_t keep = size_t(std::max(1, options_.candidates));
    for (const GlobalSearchOptions::Refinement& level : options_.refinements) keep = std::max(keep, size_t(std::max(0, level.candidates)));
    out.resize(std::min(out.size(), keep));
    std::vector<Pose> poses;
    for (const GlobalHypothesis& h : out) poses.push_back(h.pose);
    const Eigen::Vector3d none = Eigen::Vector3d::Zero();
    out = score_rotations(scale_, backend, bone_mu, poses, centre_ct, std::span(&none, 1));
    std::stable_sort(out.begin(), out.end(), by_score);
  }
  // The grid leaves the best hypothesis up to half a step off about each axis: on the pelvis CT
  // 10 to 25 mm of mean surface distance, from where the fine stages often do not converge. Finer
  // steps about each of the best few bring the right one within a few millimetres, where it also
  // correlates far better than the wrong ones (docs/registration.md, "Far starts"). Each turned
  // pose searches every shift again, so a refinement may also move to another peak; the score
  // decides, as on the grid.
  for (const GlobalSearchOptions::Refinement& level : options_.refinements) {
    if (!(level.candidates > 0 && level.step_deg > 0)) continue;
    refine(backend, bone_mu, centre_ct, level.step_deg, std::span(out.data(), std::min(out.size(), size_t(level.candidates))));
    std::stable_sort(out.begin(), out.end(), by_score);
  }
  if (out.size() > size_t(std::max(1, options_.candidates))) out.resize(size_t(std::max(1, options_.candidates)));
  return out;
}

void GlobalSearch::refine(Backend& backend, const DeviceVolume& bone_mu, const Eigen::Vector3d& centre_ct, double step_deg,
                          std::span<GlobalHypothesis> hypotheses) const {
  const double s = step_deg * std::numbers::pi / 180;
  // The hypothesis itself, re-scored about its own centre (its grid score solved the translation
  // about the start's) and kept on a tie, and a step either way about each axis: one batch.
  std::vector<Eigen::Vector3d> offsets{Eigen::Vector3d::Zero()};
  for (int a = 0; a < 3; ++a)
    for (const double sign : {-1.0, 1.0}) offsets.push_back(sign * s * Eigen::Vector3d::Unit(a));
  std::vector<Pose> starts;
  for (const GlobalHypothesis& h : hypotheses) starts.push_back(h.pose);
  const std::vector<GlobalHypothesis> probes = score_rotations(scale_, backend, bone_mu, starts, centre_ct, offsets);
  // Per axis, the vertex of the parabola through the three scores (within a step; the better end
  // where the scores do not bend down): together, one turn that may be oblique to every axis,
  // scored in a second batch. This costs 8 rotations a hypothesis where the 26 neighbours of a
  // grid did 27, and on the far-start sweeps it found as many right poses or more (docs/benchmarks.md,
  // "The search's refinement by parabolas").
  std::vector<Pose> vertices;
  std::vector<size_t> of;
  for (size_t h = 0; h < hypotheses.size(); ++h) {
    const GlobalHypothesis* p = probes.data() + h * offsets.size();
    Eigen::Vector3d w = Eigen::Vector3d::Zero();
    for (int a = 0; a < 3; ++a) w[a] = parabola_vertex(p[1 + 2 * a].score, p[0].score, p[2 + 2 * a].score) * s;
    hypotheses[h] = *std::min_element(p, p + offsets.size(), by_score);  // the first best: the hypothesis on a tie
    // A turn along one axis by a whole step, or none, was probed already.
    const long moved = (w.array().abs() > 1e-6 * s).count();
    if (moved > 1 || (moved == 1 && std::abs(w.cwiseAbs().maxCoeff() - s) > 1e-6 * s)) {
      vertices.push_back(turned_about_centre(p[0].pose, centre_ct, w));
      of.push_back(h);
    }
  }
  if (vertices.empty()) return;
  const std::vector<GlobalHypothesis> scored =
      score_rotations(scale_, backend, bone_mu, vertices, centre_ct, std::span(offsets.data(), 1));
  for (size_t i = 0; i < of.size(); ++i)
    if (scored[i].score > hypotheses[of[i]].score) hypotheses[of[i]] = scored[i];
}

std::vector<GlobalHypothesis> GlobalSearch::score_rotations(const Scale& scale, Backend& backend, const DeviceVolume& bone_mu,
                                                            std::span<const Pose> starts, const Eigen::Vector3d& centre_ct,
                                                            std::span<const Eigen::Vector3d> rotation_vectors) const {
  std::vector<PinholeCamera> cameras;
  for (const View& v : scale.views) cameras.push_back(v.camera);
  const size_t n_views = scale.views.size(), n_rotations = rotation_vectors.size();
  struct Linearisation {
    Eigen::Vector3d centre;                                // world; every rotation turns about it
    std::vector<Eigen::Matrix<double, 2, 3>> jacobian;     // per view
    Eigen::LDLT<Eigen::Matrix3d> solver;                   // of the normal equations
  };
  std::vector<Linearisation> about;
  std::vector<Pose> turned;
  for (const Pose& start : starts) {
    Linearisation l;
    l.centre = start * centre_ct;
    // How the bone centre's projection moves per millimetre of world translation, per view.
    l.jacobian.resize(n_views);
    for (size_t v = 0; v < n_views; ++v) {
      const Eigen::Vector2d p0 = cameras[v].project(l.centre);
      for (int a = 0; a < 3; ++a) l.jacobian[v].col(a) = cameras[v].project(l.centre + Eigen::Vector3d::Unit(a)) - p0;
    }
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    for (const auto& j : l.jacobian) normal += j.transpose() * j;
    normal += 1e-6 * normal.trace() * Eigen::Matrix3d::Identity();  // two parallel views leave depth free
    l.solver.compute(normal);
    for (const Eigen::Vector3d& w : rotation_vectors) turned.push_back(turned_about_centre(start, centre_ct, w));
    about.push_back(std::move(l));
  }
  // One backend batch for every start and rotation.
  const std::vector<Image> drrs = backend.drr(bone_mu, turned, cameras, DrrParams{options_.step_mm, {}});

  std::vector<GlobalHypothesis> out(turned.size());
  tbb::parallel_for(size_t(0), turned.size(), [&](size_t k) {
    const Linearisation& l = about[k / n_rotations];
    std::vector<cv::Mat> surfaces(n_views);
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    for (size_t v = 0; v < n_views; ++v) {
      const Image& d = drrs[k * n_views + v];
      cv::Mat spectra[2], product, sum;
      derivative_spectra(mat_view(d), options_.blur_px, 1.0, scale.padded, spectra);
      for (int a = 0; a < 2; ++a) {
        cv::mulSpectrums(scale.views[v].spectrum[a], spectra[a], product, 0, /*conjB=*/true);
        sum = a == 0 ? product.clone() : sum + product;
      }
      cv::idft(sum, surfaces[v], cv::DFT_REAL_OUTPUT);
      // The shift this view asks for: the correlation's peak within the searched range.
      double best = -2;
      Eigen::Vector2d shift = Eigen::Vector2d::Zero();
      const int max_shift = scale.max_shift;
      const cv::Size padded = scale.padded;
      for (int sy = -max_shift; sy <= max_shift; ++sy)
        for (int sx = -max_shift; sx <= max_shift; ++sx) {
          const float r = surfaces[v].at<float>((sy + padded.height) % padded.height, (sx + padded.width) % padded.width);
          if (r > best) {
            best = r;
            shift = {sx, sy};
          }
        }
      rhs += l.jacobian[v].transpose() * shift;
    }
    // One translation for every view; each view then scores the shift it actually gets.
    const Eigen::Vector3d t = l.solver.solve(rhs);
    double score = 0;
    for (size_t v = 0; v < n_views; ++v) {
      const Eigen::Vector2d s = l.jacobian[v] * t;
      score += read_shift(surfaces[v], s.x(), s.y());
    }
    Pose shifted = turned[k];
    shifted.translation() += t;
    // idft without scaling returns the sum times the padded image's pixel count.
    out[k] = {shifted, score / double(n_views) / double(scale.padded.area())};
  });
  return out;
}

}  // namespace fluoro
