#include "pipelines/distal_locking/nail_pose.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "engine/pose.hpp"
#include "pipelines/distal_locking/nail_image_fit.hpp"

namespace fluoro {
namespace {

// How far the hole axes may be from the drill guide's: the guide is positioned roughly on the
// holes before the shot (the scene generator: up to 5 degrees), three times that is no mounting.
constexpr double kMaxAxesOffGuideDeg = 15.0;

// A rotation with the given x and (approximately) z axes: z is made orthogonal to x.
Eigen::Matrix3d frame_from_x_z(const Eigen::Vector3d& x, const Eigen::Vector3d& z_hint) {
  const Eigen::Vector3d X = x.normalized();
  Eigen::Vector3d Z = z_hint - z_hint.dot(X) * X;
  if (Z.norm() < 1e-9) Z = X.unitOrthogonal();
  Z.normalize();
  Eigen::Matrix3d R;
  R << X, Z.cross(X), Z;
  return R;
}

bool holes_symmetric_in_x(const NailModel& nail) {
  for (const auto& h : nail.holes) {
    bool found = false;
    for (const auto& o : nail.holes)
      found = found || (std::abs(o.center_mm.x() + h.center_mm.x()) < 0.01 && std::abs(o.diameter_mm - h.diameter_mm) < 0.01);
    if (!found) return false;
  }
  return true;
}

}  // namespace

CameraPose nearest_symmetric_pose(const CameraPose& pose, const NailModel& nail, const Eigen::Vector3d& guide_x,
                                  const Eigen::Vector3d& guide_z) {
  std::vector<Eigen::Matrix3d> turns = {Eigen::Matrix3d::Identity(), Eigen::Vector3d(1, -1, -1).asDiagonal()};
  if (holes_symmetric_in_x(nail)) {
    turns.push_back(Eigen::Vector3d(-1, 1, -1).asDiagonal());
    turns.push_back(Eigen::Vector3d(-1, -1, 1).asDiagonal());
  }
  CameraPose best = pose;
  double score = -1e9;
  for (const auto& S : turns) {
    const Eigen::Matrix3d R = pose.linear() * S;
    const double s = R.col(0).dot(guide_x) + R.col(2).dot(guide_z);
    if (s > score) score = s, best.linear() = R;
  }
  return best;
}

NailPoseEstimate fronto_parallel_nail_pose(const NailDetection& det, const NailModel& nail, const Eigen::Matrix3d& K,
                                           const Eigen::Vector3d& guide_x, const Eigen::Vector3d& guide_z,
                                           const std::vector<double>& hole_depths_mm) {
  NailPoseEstimate out;
  if (det.holes.size() != nail.holes.size() || nail.holes.size() < 2 ||
      (!hole_depths_mm.empty() && hole_depths_mm.size() != det.holes.size())) {
    out.failure_reason = "holes not separable";
    return out;
  }
  // Model holes in the order of their x; detections are ordered along the band.
  std::vector<double> xs;
  double d_world = 0, d_image = 0;
  for (const auto& h : nail.holes) xs.push_back(h.center_mm.x()), d_world += h.diameter_mm;
  std::sort(xs.begin(), xs.end());
  for (const auto& e : det.holes) d_image += e.major_px;
  d_world /= double(nail.holes.size());
  d_image /= double(det.holes.size());
  const double f = 0.5 * (K(0, 0) + K(1, 1));
  // z = f d_world / d_image is the depth of what bounds the lens: the hole's far wall, where it
  // leaves the rod (sqrt(R^2 - r^2) beyond the nail's axis at the hole's rim).
  const double r = 0.5 * nail.diameter_mm, rh = 0.5 * d_world;
  const double z = f * d_world / d_image - std::sqrt(std::max(0.0, r * r - rh * rh));
  const Eigen::Matrix3d Kinv = K.inverse();
  std::vector<Eigen::Vector3d> P;
  for (size_t k = 0; k < det.holes.size(); ++k) {
    const auto& e = det.holes[k];
    P.push_back((hole_depths_mm.empty() ? z : hole_depths_mm[k]) * (Kinv * Eigen::Vector3d(e.centre_px.x(), e.centre_px.y(), 1)));
  }
  Eigen::Vector3d x = (P.back() - P.front()).normalized();
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < P.size(); ++k) origin += P[k] - xs[k] * x;
  origin /= double(P.size());
  // Fronto-parallel: the hole centres lie on the plane through the nail's centre square to the ray
  // there, so only the centre's depth is taken from the depths given. Each hole's own depth put
  // the long axis out of that plane by the depths' difference, and with the axes square to the
  // long axis it turned them off the ray by as much (0.1-0.4 degrees at tilt 0, the generic fit's
  // error in the holes' relative depth).
  for (int round = 0; round < 2; ++round) {
    const Eigen::Vector3d n = origin.normalized();
    for (size_t k = 0; k < P.size(); ++k) {
      const Eigen::Vector3d ray = Kinv * Eigen::Vector3d(det.holes[k].centre_px.x(), det.holes[k].centre_px.y(), 1);
      P[k] = ray * (origin.dot(n) / ray.dot(n));
    }
    x = (P.back() - P.front()).normalized();
    origin.setZero();
    for (size_t k = 0; k < P.size(); ++k) origin += P[k] - xs[k] * x;
    origin /= double(P.size());
  }
  CameraPose T = CameraPose::Identity();
  T.linear() = frame_from_x_z(x, origin);  // hole axes along the ray to the nail's centre
  T.translation() = origin;
  // A turn about the nail's z swaps the holes: resolve x by the guide as the seed does.
  out.T_camera_nail = nearest_symmetric_pose(T, nail, guide_x, guide_z);
  if (!holes_symmetric_in_x(nail) && out.T_camera_nail.linear().col(0).dot(x) < 0) {
    // Unequal holes cannot be swapped: keep the detection's order.
    out.T_camera_nail = T;
  }
  out.ok = true;
  return out;
}

NailPoseEstimate fit_nail_pose(const Image& xray, const NailModel& nail, const Eigen::Matrix3d& K,
                               const std::vector<CameraPose>& starts, double band_width_px,
                               const std::vector<DarkCircle>& occluders, const Eigen::Vector3d& guide_x,
                               const Eigen::Vector3d& guide_z) {
  NailPoseEstimate out;
  if (starts.empty()) {
    out.failure_reason = "no start for the nail's pose";
    return out;
  }
  NailImageModel model(xray, nail, K, starts.front(), band_width_px, occluders);
  if (!model.usable()) {
    out.failure_reason = "holes not separable: too little of the nail visible around its holes";
    return out;
  }
  // From each start: its depth (from the band's width, whose edges the blur pulls inwards) can be
  // 10 % off, too far for the fit to recover, so a line search along the ray to the nail first;
  // then a coarse fit (one ray per pixel, 2 x 2 on narrow bands).
  struct Candidate {
    CameraPose pose;
    NailImaging imaging;
    double rms;
  };
  std::vector<Candidate> coarse;
  for (const CameraPose& start : starts) {
    model.set_rays(start, true);
    CameraPose from = start;
    double best = HUGE_VAL;
    // Every 2 %, then 1 % either side of the best.
    double best_scale = 1.0;
    const auto probe = [&](double scale) {
      CameraPose T = start;
      T.translation() *= scale;
      const double r = model.rms(T, NailImaging{});
      ++out.evaluations;
      if (r < best) best = r, from = T, best_scale = scale;
    };
    for (int i = 0; i <= 20; ++i) probe(0.80 + 0.02 * i);
    const double centre = best_scale;
    probe(centre - 0.01);
    probe(centre + 0.01);
    Candidate c{from, {}, 0};
    c.pose = model.fit(from, &c.imaging, true, &c.rms, &out.evaluations);
    coarse.push_back(c);
  }
  std::sort(coarse.begin(), coarse.end(), [](const Candidate& x, const Candidate& y) { return x.rms < y.rms; });
  // The single view's ambiguity: mirroring the hole axes in the plane through the source and the
  // nail's long axis leaves the rod's image unchanged. The best coarse fit's mirror image is
  // always fitted (coarsely, then finely if it is not clearly worse): an earlier version fitted it
  // only when its unfitted residual was within 1.5 times the best's, and a tilt-15 image whose
  // start along the guide had stopped short (numerical Jacobian) ended 31.7 degrees off because
  // the true pose, the mirror of the wrong one, was never fitted (docs/distal_locking.md).
  Candidate mirror;
  {
    const Candidate& a = coarse.front();
    const Eigen::Vector3d x = a.pose.linear().col(0), m = x.cross(a.pose.translation()).normalized();
    const Eigen::Vector3d z = a.pose.linear().col(2);
    mirror = a;
    mirror.pose.linear() = frame_from_x_z(x, z - 2 * z.dot(m) * m);
    model.set_rays(mirror.pose, true);
    mirror.pose = model.fit(mirror.pose, &mirror.imaging, true, &mirror.rms, &out.evaluations);
    out.mirror_rms = mirror.rms;
    coarse.push_back(mirror);
    std::sort(coarse.begin(), coarse.end(), [](const Candidate& x, const Candidate& y) { return x.rms < y.rms; });
  }
  // Starts that ended in the same minimum (0.2 degrees, 0.5 mm) are fitted finely once.
  for (size_t i = 1; i < coarse.size();) {
    bool same = false;
    for (size_t j = 0; j < i && !same; ++j)
      same = rotation_angle_deg(coarse[j].pose.inverse() * coarse[i].pose) < 0.2 &&
             (coarse[j].pose.translation() - coarse[i].pose.translation()).norm() < 0.5;
    // A start that ended clearly worse (rms 1.2 times the best's: the coarse rays' sampling error
    // moves the rms by about 4 %, a tie at the fine level is 0.2 % of the sum of squares) is not
    // fitted finely either (the best one's mirror image was fitted coarsely above).
    same = same || coarse[i].rms > 1.2 * coarse.front().rms;
    if (same) coarse.erase(coarse.begin() + long(i));
    else ++i;
  }
  // Then fine (supersampled edges), every candidate on the same pixels: what the model cannot
  // explain is left out at the best coarse pose (trimming on single rays would take the edges'
  // sampling error for outliers, so the fine rays come first). The blur and the attenuation are
  // fitted with the pose.
  model.set_rays(coarse.front().pose, false);
  model.trim(coarse.front().pose, coarse.front().imaging);
  std::vector<Candidate> fine;
  for (const Candidate& c : coarse) {
    Candidate f = c;
    model.set_rays(c.pose, false);
    f.pose = model.fit(c.pose, &f.imaging, true, &f.rms, &out.evaluations);
    fine.push_back(f);
  }
  std::sort(fine.begin(), fine.end(), [](const Candidate& x, const Candidate& y) { return x.rms < y.rms; });
  // Fits the image cannot tell apart (their sums of squares within 25 noise variances, the
  // noise taken as the best fit's rms) are decided by the guide: the one whose hole axes are
  // nearest the guide's axes, as the seed resolves its ambiguities.
  const double best_rms = std::min_element(fine.begin(), fine.end(), [](const Candidate& x, const Candidate& y) {
                            return x.rms < y.rms;
                          })->rms;
  const double n = double(std::max(1, model.residual_count()));
  const double tie = best_rms * best_rms * (1.0 + 25.0 / n);
  const Candidate* chosen = nullptr;
  double nearest = -HUGE_VAL;
  for (const Candidate& c : fine) {
    if (c.rms * c.rms > tie) continue;
    const double near = nearest_symmetric_pose(c.pose, nail, guide_x, guide_z).linear().col(2).dot(guide_z);
    if (near > nearest) nearest = near, chosen = &c;
  }
  for (const Candidate& c : fine)
    if (&c != chosen && rotation_angle_deg(c.pose.inverse() * mirror.pose) < 1.0) out.mirror_rms = c.rms;
  // A fit that explains the image best with (almost) no metal has not found the nail.
  if (chosen->imaging.attenuation_per_mm <= kMinNailAttenuationPerMm * 1.001) {
    out.failure_reason = "nail pose not resolved: the image fit explains the holes' windows without a nail (attenuation at its bound)";
    return out;
  }
  out.T_camera_nail = nearest_symmetric_pose(chosen->pose, nail, guide_x, guide_z);
  for (const Candidate& c : fine)
    if (&c != chosen && c.rms * c.rms <= tie)
      out.tie_spread_deg = std::max(out.tie_spread_deg, axis_angle_deg(nearest_symmetric_pose(c.pose, nail, guide_x, guide_z).linear().col(2),
                                                                       out.T_camera_nail.linear().col(2)));
  // The guide is brought roughly onto the holes before the shot (the fit starts there): hole axes
  // far from the guide's mean a minimum the image did not decide, and it is flagged, not reported.
  const double off_guide = axis_angle_deg(out.T_camera_nail.linear().col(2), guide_z);
  if (off_guide > kMaxAxesOffGuideDeg) {
    char reason[160];
    std::snprintf(reason, sizeof reason,
                  "nail pose not resolved: the best fit's hole axes are %.1f degrees from the drill guide's (at most %.0f expected)",
                  off_guide, kMaxAxesOffGuideDeg);
    out.failure_reason = reason;
    return out;
  }
  out.rms = chosen->rms;
  out.attenuation_per_mm = chosen->imaging.attenuation_per_mm;
  out.blur_px = chosen->imaging.blur_px;
  out.ok = true;
  return out;
}

}  // namespace fluoro
