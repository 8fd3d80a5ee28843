#pragma once
// Where a ray from the origin meets a solid circular cylinder: the exact interval of ray parameters
// inside it. The X-ray of a nail (a cylinder with cylindrical through-holes) and of a bone tube is a
// sum and difference of such chords, used both to render test scenes and to fit the nail's pose.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace fluoro {

// A closed interval [lo, hi] of ray parameter; empty when hi <= lo.
struct RayInterval {
  double lo = 0, hi = 0;
  double length() const { return hi > lo ? hi - lo : 0.0; }
  RayInterval intersect(const RayInterval& o) const { return {std::max(lo, o.lo), std::min(hi, o.hi)}; }
};

// A cylinder: a point on its axis, the axis' unit direction, the radius and, along the axis from
// the point, the extent [s0, s1] (infinite by default).
struct Cylinder {
  Eigen::Vector3d point;
  Eigen::Vector3d axis;
  double radius = 0;
  double s0 = -HUGE_VAL, s1 = HUGE_VAL;
};

// The part of the ray {t d : t >= 0} (d a unit vector) inside the cylinder; t is in mm along d.
inline RayInterval ray_in_cylinder(const Cylinder& c, const Eigen::Vector3d& d) {
  const double dw = d.dot(c.axis), aw = c.point.dot(c.axis);
  const Eigen::Vector3d dp = d - dw * c.axis, ap = c.point - aw * c.axis;
  const double A = dp.squaredNorm(), B = dp.dot(ap), C = ap.squaredNorm() - c.radius * c.radius;
  RayInterval in;
  if (A < 1e-15) {  // ray along the axis: inside everywhere or nowhere
    if (C > 0) return {};
    in = {0.0, HUGE_VAL};
  } else {
    const double disc = B * B - A * C;
    if (disc <= 0) return {};
    const double s = std::sqrt(disc);
    in = {(B - s) / A, (B + s) / A};
  }
  if (std::isfinite(c.s0) || std::isfinite(c.s1)) {
    // Axial coordinate along the ray: t * dw - aw, within [s0, s1].
    if (std::abs(dw) < 1e-15) {
      if (-aw < c.s0 || -aw > c.s1) return {};
    } else {
      double t0 = (c.s0 + aw) / dw, t1 = (c.s1 + aw) / dw;
      if (t0 > t1) std::swap(t0, t1);
      in = in.intersect({t0, t1});
    }
  }
  in.lo = std::max(in.lo, 0.0);
  return in;
}

}  // namespace fluoro
