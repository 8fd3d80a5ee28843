#include "pipelines/distal_locking/distal_locking.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "engine/pose.hpp"

namespace fluoro {
namespace {

constexpr double kMinHoleOutline = 0.5;  // of the hole's expected diameter in the image

double seconds_since_start(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}


// The generic fit's start: the fronto-parallel pose with its hole axes turned onto the guide's
// axis direction (the guide is mounted roughly aligned; which is why it is there), its depth from
// the band's width (more pixels than the holes' diameters).
CameraPose generic_start(const NailPoseEstimate& fronto, const NailDetection& det, const NailModel& nail,
                         const Eigen::Matrix3d& K, const Eigen::Vector3d& z_axis) {
  // The hole axes exactly along `z_axis`; the long axis, seen only in the image's plane (the
  // holes' centres at one depth), gives way to it: a nail tilted along its length would otherwise
  // turn the hole axes away from the guide's by the tilt.
  CameraPose T = fronto.T_camera_nail;
  const Eigen::Vector3d z = z_axis.normalized();
  Eigen::Vector3d x = T.linear().col(0) - T.linear().col(0).dot(z) * z;
  if (x.norm() > 1e-6) {
    x.normalize();
    T.linear() << x, z.cross(x), z;
  }
  const double f = 0.5 * (K(0, 0) + K(1, 1));
  const double depth = f * nail.diameter_mm / det.band.width_px;
  T.translation() *= depth / T.translation().z();
  return T;
}

}  // namespace

DistalLocking locate_for_distal_locking(const Image& xray, const PinholeCamera& camera, const DrillGuideModel& guide,
                                        const NailModel& nail, NailMode mode) {
  DistalLocking out;
  const Eigen::Matrix3d& K = camera.K;
  const Eigen::Isometry3d T_camera_world = camera.camera_from_world();

  auto t0 = std::chrono::steady_clock::now();
  out.guide = localise_guide(xray, guide, K);
  out.spheres_seconds = seconds_since_start(t0);
  out.guide_ok = out.guide.localisation.ok;
  if (!out.guide_ok) {
    out.failure_reason = out.guide.localisation.failure_reason;
    return out;
  }
  out.T_camera_guide = out.guide.localisation.T_camera_guide;
  out.T_world_guide = T_camera_world.inverse() * out.T_camera_guide;
  const Eigen::Vector3d guide_x = out.T_camera_guide.linear().col(0), guide_z = out.T_camera_guide.linear().col(2);

  t0 = std::chrono::steady_clock::now();
  const double f = 0.5 * (K(0, 0) + K(1, 1));
  // Every guide sphere, found or not, is an occluder of the nail's image: left out of its holes'
  // outlines and of the fit.
  std::vector<DarkCircle> occluders = out.guide.circles;
  for (const auto& X : guide.spheres_mm) {
    DarkCircle c;
    c.centre_px = project_pose(K, out.T_camera_guide, X);
    c.radius_px = f * 0.5 * guide.sphere_diameter_mm / (out.T_camera_guide * X).z();
    occluders.push_back(c);
  }
  out.nail_detection =
      detect_nail(xray, nail, f * nail.diameter_mm / 1500.0, f * nail.diameter_mm / 300.0, occluders);
  out.nail_detection_seconds = seconds_since_start(t0);
  if (!out.nail_detection.ok) {
    out.failure_reason = out.nail_detection.failure_reason;
    return out;
  }

  // A hole's outline must be about a hole across: its minor axis (across the nail, where a tilt
  // does not shorten it) at least half the hole's diameter at the band's scale. A sliver is a
  // bright seam between occluders or clutter, not a hole; reporting a pose from it put the nail
  // 25-90 mm off in 5 of 264 sweep images (docs/distal_locking.md).
  {
    double hole_d = 0;
    for (const auto& h : nail.holes) hole_d += h.diameter_mm / double(nail.holes.size());
    const double expected_px = out.nail_detection.band.width_px * hole_d / nail.diameter_mm;
    for (size_t k = 0; k < out.nail_detection.holes.size(); ++k)
      if (out.nail_detection.holes[k].minor_px < kMinHoleOutline * expected_px) {
        char reason[200];
        std::snprintf(reason, sizeof reason,
                      "holes not separable: hole %zu's outline is %.1f px across, a hole there is %.1f px (a sliver, not a hole)", k,
                      out.nail_detection.holes[k].minor_px, expected_px);
        out.failure_reason = reason;
        return out;
      }
  }

  t0 = std::chrono::steady_clock::now();
  const NailPoseEstimate fronto = fronto_parallel_nail_pose(out.nail_detection, nail, K, guide_x, guide_z);
  if (!fronto.ok) {
    out.failure_reason = fronto.failure_reason;
    return out;
  }
  {
    // Two starts: hole axes along the guide's axes (it is mounted roughly aligned) and along the
    // ray to the nail (the fronto-parallel view the technician aims for).
    const CameraPose along_guide = generic_start(fronto, out.nail_detection, nail, K, guide_z);
    const CameraPose along_ray = generic_start(fronto, out.nail_detection, nail, K, fronto.T_camera_nail.linear().col(2));
    out.nail_pose = fit_nail_pose(xray, nail, K, {along_guide, along_ray}, out.nail_detection.band.width_px, occluders,
                                  guide_x, guide_z);
  }
  // The single view's ambiguity, decided by the guide, is a guess when the fits it chose between
  // are further apart than the axis accuracy asked of the pose (the big sweep: 3 of its 4 wrong
  // generic poses, 1.5 to 3.6 degrees off, were such ties). The interactive mode takes its axes
  // from the rays, not from these fits.
  if (mode == NailMode::generic && out.nail_pose.ok && out.nail_pose.tie_spread_deg > kMaxTieSpreadDeg) {
    char reason[300];
    std::snprintf(reason, sizeof reason,
                  "nail pose ambiguous: two fits whose hole axes are %.1f degrees apart explain the image alike "
                  "(one view leaves them undecided, and the guide can decide only within %.0f degree): "
                  "take another image, tilted a few more degrees from the holes' axes or with more dose",
                  out.nail_pose.tie_spread_deg, kMaxTieSpreadDeg);
    out.nail_pose.ok = false;
    out.nail_pose.failure_reason = reason;
  }
  // The hole axes' deviation from the rays, for the technician, is the generic fit's in both modes
  // (the fronto-parallel pose has none by construction).
  const CameraPose fitted = out.nail_pose.T_camera_nail;
  if (out.nail_pose.ok) {
    out.view_deviation_deg = axis_angle_deg(fitted.translation(), fitted.linear().col(2));
    out.fronto_parallel = out.view_deviation_deg <= kFrontoParallelDeg;
  }
  if (mode == NailMode::interactive && out.nail_pose.ok) {
    // The seed's pose (centres from the holes' outlines, axes along the rays) at the depth of the
    // cylinder fit's hole centres: the outlines' diameters, read at half contrast in the log
    // domain, are widened by the blur (25-40 mm of depth).
    std::vector<double> depths;
    for (const auto& e : out.nail_detection.holes) {
      const NailHole* nearest = nullptr;
      for (const auto& h : nail.holes)
        if (!nearest || (project_pose(K, fitted, h.center_mm) - e.centre_px).norm() <
                            (project_pose(K, fitted, nearest->center_mm) - e.centre_px).norm())
          nearest = &h;
      depths.push_back((fitted * nearest->center_mm).z());
    }
    const NailPoseEstimate image_fit = out.nail_pose;
    out.nail_pose = fronto_parallel_nail_pose(out.nail_detection, nail, K, guide_x, guide_z, depths);
    // The image fit that placed the depths (and measured the view) is the one there is: its
    // quality is the report's in this mode too, rather than the zeros of a pose fitted to nothing.
    out.nail_pose.rms = image_fit.rms;
    out.nail_pose.mirror_rms = image_fit.mirror_rms;
    out.nail_pose.tie_spread_deg = image_fit.tie_spread_deg;
    out.nail_pose.evaluations = image_fit.evaluations;
    out.nail_pose.attenuation_per_mm = image_fit.attenuation_per_mm;
    out.nail_pose.blur_px = image_fit.blur_px;
  }
  out.nail_pose_seconds = seconds_since_start(t0);
  if (!out.nail_pose.ok) {
    out.failure_reason = out.nail_pose.failure_reason;
    return out;
  }
  out.nail_ok = true;
  out.T_camera_nail = out.nail_pose.T_camera_nail;
  out.T_world_nail = T_camera_world.inverse() * out.T_camera_nail;

  // Entry and exit: the hole's axis meets the rod's surface at z = -+R in the nail's frame; the
  // entry is the one nearer the guide's spheres.
  Eigen::Vector3d guide_centre = Eigen::Vector3d::Zero();
  for (const auto& X : guide.spheres_mm) guide_centre += X;
  guide_centre = out.T_camera_guide * (guide_centre / double(guide.spheres_mm.size()));
  const double r = 0.5 * nail.diameter_mm;
  for (const auto& h : nail.holes) {
    HoleAxisPoints p;
    const Eigen::Vector3d a = out.T_camera_nail * (h.center_mm - Eigen::Vector3d(0, 0, r));
    const Eigen::Vector3d b = out.T_camera_nail * (h.center_mm + Eigen::Vector3d(0, 0, r));
    const bool a_first = (a - guide_centre).norm() <= (b - guide_centre).norm();
    p.entry_mm = T_camera_world.inverse() * (a_first ? a : b);
    p.exit_mm = T_camera_world.inverse() * (a_first ? b : a);
    // The interactive scores: the detected ellipse nearest the hole's projected centre.
    const Eigen::Vector2d c = project_pose(K, out.T_camera_nail, h.center_mm);
    const HoleEllipse* e = nullptr;
    for (const auto& d : out.nail_detection.holes)
      if (!e || (d.centre_px - c).norm() < (e->centre_px - c).norm()) e = &d;
    if (e && e->lens_major_px > 0) p.circularity = e->lens_minor_px / e->lens_major_px;
    const Eigen::Vector3d ray_fit = (fitted * h.center_mm).normalized();
    p.deviation_deg = std::acos(std::min(1.0, std::abs(ray_fit.dot(fitted.linear().col(2))))) * 180.0 / std::numbers::pi;
    out.holes.push_back(p);
  }
  out.ok = true;
  return out;
}

}  // namespace fluoro
