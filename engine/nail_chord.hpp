#pragma once
// The length of metal a ray crosses in an intramedullary nail: a solid cylinder (NAIL.json's
// diameter, along the nail's x) minus its cylindrical locking holes (along the nail's z). Exact,
// from ray-cylinder intervals: the hole's visible lens shrinks as the view tilts, as in an X-ray.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "engine/distal_locking_models.hpp"
#include "engine/ray_cylinder.hpp"

namespace fluoro {

// A nail placed in the camera frame (x_cam = R x_nail + t), as cylinders ready for ray queries.
struct PlacedNail {
  Cylinder rod;
  std::vector<Cylinder> holes;
};

// `x_min`, `x_max`: the rod's extent along its axis in the nail's frame (infinite by default).
inline PlacedNail place_nail(const NailModel& nail, const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                             double x_min = -HUGE_VAL, double x_max = HUGE_VAL) {
  PlacedNail p;
  p.rod = {t, R.col(0), 0.5 * nail.diameter_mm, x_min, x_max};
  for (const auto& h : nail.holes) p.holes.push_back({R * h.center_mm + t, R.col(2), 0.5 * h.diameter_mm});
  return p;
}

// Metal chord (mm) along the unit ray direction d from the source (camera origin).
inline double nail_chord_mm(const PlacedNail& n, const Eigen::Vector3d& d) {
  const RayInterval rod = ray_in_cylinder(n.rod, d);
  if (rod.length() <= 0) return 0.0;
  double len = rod.length();
  for (const auto& h : n.holes) len -= rod.intersect(ray_in_cylinder(h, d)).length();
  return len;
}

// Derivative of a ray-cylinder interval endpoint `t` (a root on the cylinder's surface) with
// respect to moving the cylinder rigidly: a rotation w (radians, about `origin`) and a translation
// v, as d t = g.head(3) . w + g.tail(3) . v. Implicit differentiation of |q|^2 = r^2, q the offset
// of the point t d from the axis: d t = (q . dc + (w.a) q . da) / (q . d), with dc = w x m + v
// (m = point - origin) and da = w x a. At a ray tangent to the surface q . d -> 0 and the derivative
// grows without bound (the chord's square-root edge); its singular factor is capped at `cap`,
// which only a sample within ~r/(2 cap^2) of the tangent reaches: the cost is evaluated exactly,
// so the cap only shortens a fit's step there, it does not move its minimum noticeably.
inline Eigen::Matrix<double, 6, 1> ray_cylinder_endpoint_gradient(const Cylinder& c, const Eigen::Vector3d& origin,
                                                                  const Eigen::Vector3d& d, double t, double cap = 20.0) {
  const Eigen::Vector3d w = t * d - c.point;
  const double wa = w.dot(c.axis);
  const Eigen::Vector3d q = w - wa * c.axis;
  double qd = q.dot(d);
  // |q . d| = |q| |d_perp| |cos phi|, phi the angle about the axis from the ray's own direction
  // across it: the singular factor is cos phi alone (a ray nearly along a hole's axis meets its
  // wall at a glancing angle everywhere, and that large derivative is real).
  const double floor = q.norm() * (d - d.dot(c.axis) * c.axis).norm() / cap;
  if (std::abs(qd) < floor) qd = std::copysign(floor, qd);
  Eigen::Matrix<double, 6, 1> g;
  if (!(std::abs(qd) > 0)) return Eigen::Matrix<double, 6, 1>::Zero();
  const Eigen::Vector3d m = c.point - origin;
  g.head<3>() = (m.cross(q) + wa * c.axis.cross(q)) / qd;
  g.tail<3>() = q / qd;
  return g;
}

// The chord (as nail_chord_mm) and its gradient with respect to a rigid motion of the whole nail:
// a rotation w (radians) about the nail's origin (the rod's axis point, place_nail's t) and a
// translation v, both in the camera frame; gradient order (w, v). Endpoints clamped at the source
// (t = 0) or at infinity have no gradient (a nail in front of the source has neither).
// `cap`: ray_cylinder_endpoint_gradient's. The nail fit uses 5: a few of a pixel's rays near a
// tangent otherwise dominate its Jacobian with spikes that the pixel's area would average out, and
// the fit stopped early (a tilt-2.5 image ended 3.6 degrees off at cap 20, 0.16 at 5).
inline double nail_chord_gradient(const PlacedNail& n, const Eigen::Vector3d& d, Eigen::Matrix<double, 6, 1>* grad,
                                  double cap = 5.0) {
  grad->setZero();
  const RayInterval rod = ray_in_cylinder(n.rod, d);
  if (rod.length() <= 0) return 0.0;
  const Eigen::Vector3d& origin = n.rod.point;
  const auto endpoint = [&](const Cylinder& c, double t) -> Eigen::Matrix<double, 6, 1> {
    if (t <= 0 || !std::isfinite(t)) return Eigen::Matrix<double, 6, 1>::Zero();
    return ray_cylinder_endpoint_gradient(c, origin, d, t, cap);
  };
  double len = rod.length();
  *grad = endpoint(n.rod, rod.hi) - endpoint(n.rod, rod.lo);
  for (const auto& h : n.holes) {
    const RayInterval hi = ray_in_cylinder(h, d);
    const RayInterval both = rod.intersect(hi);
    if (both.length() <= 0) continue;
    len -= both.length();
    const Eigen::Matrix<double, 6, 1> g_hi = both.hi == rod.hi ? endpoint(n.rod, rod.hi) : endpoint(h, hi.hi);
    const Eigen::Matrix<double, 6, 1> g_lo = both.lo == rod.lo ? endpoint(n.rod, rod.lo) : endpoint(h, hi.lo);
    *grad -= g_hi - g_lo;
  }
  return len;
}

}  // namespace fluoro
