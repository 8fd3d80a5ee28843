// Deterministic synthetic CT phantoms built from smooth implicit primitives.
//
// Every structure is a signed distance function (negative inside, mm) made of spheres, round cones,
// ellipsoids and rounded boxes joined by polynomial smooth-min, so surfaces (and the DRR edges and
// volume gradients derived from them) are smooth. A bone is cortical (1500 HU) within its local
// cortical thickness of the outer surface and marrow (300 HU) deeper inside. Voxels whose centre
// lies within a voxel diagonal of any tissue interface are supersampled 2x2x2.
//
// Anatomy is designed for a 256 mm field of view and scaled by fov_mm / 256, so the bone always
// lies in the central ~80% of the volume.
//
// Determinism: all random choices (std::mt19937_64, whose output the standard fixes, mapped to
// [0, 1) by our own bit arithmetic) happen before the parallel voxel loop, which writes each voxel
// from its position alone. The voxel loop uses only +, -, *, /, sqrt, floor, min, max and abs
// with a fixed evaluation order (no libm transcendental functions, no Eigen reductions whose
// order could depend on SIMD width), and the library is compiled with -ffp-contract=off, so the
// voxels are bit-identical on every IEEE-754 platform.
#include "datasets/phantom.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <random>
#include <utility>

#include "engine/error.hpp"
#include "engine/pose.hpp"

namespace fluoro {
namespace {

using V3 = Eigen::Vector3d;
using M3 = Eigen::Matrix3d;

constexpr double kInf = std::numeric_limits<double>::infinity();

constexpr double kAirHU = -1000.0;
constexpr double kSoftTissueHU = 40.0;
constexpr double kCorticalHU = 1500.0;
constexpr double kMarrowHU = 300.0;
constexpr double kFiducialHU = 2500.0;
constexpr double kMetalHU = 3000.0;

// ---------------------------------------------------------------------------------------------
// Deterministic arithmetic helpers.

double dot(const V3& a, const V3& b) { return a.x() * b.x() + a.y() * b.y() + a.z() * b.z(); }
double len(const V3& a) { return std::sqrt(dot(a, a)); }
V3 unit(const V3& a) { return a / len(a); }
V3 mul(const M3& m, const V3& v) {
  return V3(m(0, 0) * v.x() + m(0, 1) * v.y() + m(0, 2) * v.z(),
            m(1, 0) * v.x() + m(1, 1) * v.y() + m(1, 2) * v.z(),
            m(2, 0) * v.x() + m(2, 1) * v.y() + m(2, 2) * v.z());
}
M3 matmul(const M3& a, const M3& b) {
  M3 r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r(i, j) = a(i, 0) * b(0, j) + a(i, 1) * b(1, j) + a(i, 2) * b(2, j);
  return r;
}

// sin by range reduction and a Taylor series: identical on every platform, unlike libm.
double det_sin(double x) {
  x -= 2.0 * std::numbers::pi * std::floor((x + std::numbers::pi) / (2.0 * std::numbers::pi));
  const double x2 = x * x;
  double term = x, sum = x;
  for (int n = 1; n <= 14; ++n) {
    term *= -x2 / double((2 * n) * (2 * n + 1));
    sum += term;
  }
  return sum;
}
double det_cos(double x) { return det_sin(x + 0.5 * std::numbers::pi); }

M3 rot_x(double deg) {
  const double c = det_cos(radians(deg)), s = det_sin(radians(deg));
  M3 m;
  m << 1, 0, 0, 0, c, -s, 0, s, c;
  return m;
}
M3 rot_y(double deg) {
  const double c = det_cos(radians(deg)), s = det_sin(radians(deg));
  M3 m;
  m << c, 0, s, 0, 1, 0, -s, 0, c;
  return m;
}
M3 rot_z(double deg) {
  const double c = det_cos(radians(deg)), s = det_sin(radians(deg));
  M3 m;
  m << c, -s, 0, s, c, 0, 0, 0, 1;
  return m;
}

// Uniform numbers from the standard-specified mt19937_64 with our own mapping.
class Random {
 public:
  explicit Random(uint64_t seed) : engine_(seed) {}
  double uniform() { return double(engine_() >> 11) * 0x1.0p-53; }  // [0, 1)
  double range(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  double vary(double value, double fraction) { return value * range(1.0 - fraction, 1.0 + fraction); }
  int below(int n) { return std::min(n - 1, int(uniform() * n)); }  // 0 .. n-1
  // Three draws in a fixed order (the order of function arguments is unspecified).
  V3 vec(double lo, double hi) {
    const double x = range(lo, hi);
    const double y = range(lo, hi);
    const double z = range(lo, hi);
    return V3(x, y, z);
  }

 private:
  std::mt19937_64 engine_;
};

// Polynomial smooth minimum / maximum with blend radius k (mm).
double smin(double a, double b, double k) {
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::min(a, b) - h * h * k * 0.25;
}
double smax(double a, double b, double k) { return -smin(-a, -b, k); }

double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

// ---------------------------------------------------------------------------------------------
// Bounding boxes (for culling; they contain every surface they stand for).

struct Box3 {
  V3 lo = V3::Constant(kInf), hi = V3::Constant(-kInf);
  void add(const V3& c, double r) {
    lo = lo.cwiseMin(c - V3::Constant(r));
    hi = hi.cwiseMax(c + V3::Constant(r));
  }
  void add(const Box3& b) {
    lo = lo.cwiseMin(b.lo);
    hi = hi.cwiseMax(b.hi);
  }
  void grow(double m) {
    lo -= V3::Constant(m);
    hi += V3::Constant(m);
  }
  double distance(const V3& p) const {
    const V3 d = (lo - p).cwiseMax(p - hi).cwiseMax(0.0);
    return len(d);
  }
};

// ---------------------------------------------------------------------------------------------
// Primitives (signed distance, mm; negative inside).

struct Sphere {
  V3 c = V3::Zero();
  double r = 1;
  double eval(const V3& p) const { return len(p - c) - r; }
  void bound(Box3& b) const { b.add(c, r); }
};

// A capsule whose radius changes linearly from r1 at a to r2 at b (exact distance, after Inigo
// Quilez's round cone).
struct RoundCone {
  V3 a = V3::Zero(), b = V3::UnitZ(), ba = V3::UnitZ();
  double r1 = 1, r2 = 1, l2 = 1, rr = 0, a2 = 1, il2 = 1;
  RoundCone() = default;
  RoundCone(const V3& a_, const V3& b_, double r1_, double r2_) : a(a_), b(b_), r1(r1_), r2(r2_) {
    ba = b - a;
    l2 = dot(ba, ba);
    rr = r1 - r2;
    a2 = l2 - rr * rr;
    il2 = 1.0 / l2;
  }
  double eval(const V3& p) const {
    const V3 pa = p - a;
    const double y = dot(pa, ba);
    const double z = y - l2;
    const V3 w = pa * l2 - ba * y;
    const double x2 = dot(w, w);
    const double y2 = y * y * l2;
    const double z2 = z * z * l2;
    const double k = (rr > 0 ? 1.0 : rr < 0 ? -1.0 : 0.0) * rr * rr * x2;
    const double sz = z > 0 ? 1.0 : z < 0 ? -1.0 : 0.0;
    const double sy = y > 0 ? 1.0 : y < 0 ? -1.0 : 0.0;
    if (sz * a2 * z2 > k) return std::sqrt(x2 + z2) * il2 - r2;
    if (sy * a2 * y2 < k) return std::sqrt(x2 + y2) * il2 - r1;
    return (std::sqrt(x2 * a2 * il2) + y * rr) * il2 - r1;
  }
  void bound(Box3& bx) const {
    bx.add(a, r1);
    bx.add(b, r2);
  }
};

// Ellipsoid with semi-axes r along the columns of `axes` (approximate distance, exact surface).
struct Ellipsoid {
  V3 c = V3::Zero(), r = V3::Ones();
  M3 to_local = M3::Identity();  // rows: the ellipsoid's axes in world coordinates
  Ellipsoid() = default;
  Ellipsoid(const V3& c_, const V3& r_, const M3& axes = M3::Identity())
      : c(c_), r(r_), to_local(axes.transpose()) {}
  double eval(const V3& p) const {
    const V3 q = mul(to_local, p - c);
    const V3 q1 = q.cwiseQuotient(r);
    const V3 q2 = q1.cwiseQuotient(r);
    const double k0 = len(q1), k1 = len(q2);
    if (k1 < 1e-12) return -r.minCoeff();
    return k0 * (k0 - 1.0) / k1;
  }
  void bound(Box3& b) const { b.add(c, r.maxCoeff()); }
};

struct RoundBox {
  V3 c = V3::Zero(), half = V3::Ones();
  double round = 0;
  M3 to_local = M3::Identity();
  RoundBox() = default;
  RoundBox(const V3& c_, const V3& half_, double round_, const M3& axes = M3::Identity())
      : c(c_), half(half_), round(round_), to_local(axes.transpose()) {}
  double eval(const V3& p) const {
    const V3 q = mul(to_local, p - c).cwiseAbs() - (half - V3::Constant(round));
    return len(q.cwiseMax(0.0)) + std::min(q.maxCoeff(), 0.0) - round;
  }
  void bound(Box3& b) const { b.add(c, len(half)); }
};

// A plate along its local z (length 2 * half_len) whose half widths taper linearly from the top
// (+z) to the bottom and whose mid-surface bows towards local +y by `bow` at the middle
// (approximate distance; the taper and bow are gentle).
struct TaperedPlate {
  V3 c = V3::Zero();
  M3 to_local = M3::Identity();
  double half_len = 1, top_hx = 1, bottom_hx = 1, top_hy = 1, bottom_hy = 1, bow = 0, round = 0;
  double eval(const V3& p) const {
    V3 q = mul(to_local, p - c);
    const double u = std::clamp((q.z() + half_len) / (2.0 * half_len), 0.0, 1.0);
    const double hx = bottom_hx + (top_hx - bottom_hx) * u, hy = bottom_hy + (top_hy - bottom_hy) * u;
    const double s = q.z() / half_len;
    q.y() -= bow * (1.0 - s * s);
    const V3 e = q.cwiseAbs() - V3(hx - round, hy - round, half_len - round);
    return len(e.cwiseMax(0.0)) + std::min(e.maxCoeff(), 0.0) - round;
  }
  void bound(Box3& b) const {
    b.add(c, std::sqrt(top_hx * top_hx + (top_hy + std::abs(bow)) * (top_hy + std::abs(bow)) + half_len * half_len));
  }
};

// 2D ellipse, approximate distance.
double ellipse_distance(double x, double y, double a, double b) {
  const double u = x / a, v = y / b;
  const double k0 = std::sqrt(u * u + v * v);
  const double u2 = u / a, v2 = v / b;
  const double k1 = std::sqrt(u2 * u2 + v2 * v2);
  if (k1 < 1e-12) return -std::min(a, b);
  return k0 * (k0 - 1.0) / k1;
}

// Elliptic cylinder along its local z with rounded rims.
struct EllipticCylinder {
  V3 c = V3::Zero();
  double rx = 1, ry = 1, half_h = 1, round = 0;
  M3 to_local = M3::Identity();
  double eval(const V3& p) const {
    const V3 q = mul(to_local, p - c);
    const double dr = ellipse_distance(q.x(), q.y(), rx - round, ry - round);
    const double dz = std::abs(q.z()) - (half_h - round);
    const double ox = std::max(dr, 0.0), oz = std::max(dz, 0.0);
    return std::min(std::max(dr, dz), 0.0) + std::sqrt(ox * ox + oz * oz) - round;
  }
  void bound(Box3& b) const { b.add(c, std::sqrt(std::max(rx, ry) * std::max(rx, ry) + half_h * half_h)); }
};

// ---------------------------------------------------------------------------------------------
// Bones: the outer surface distance and the local cortical thickness, both in world mm.

struct BoneSample {
  double d;  // signed distance to the outer surface
  double t;  // cortical thickness here
};

class Bone {
 public:
  virtual ~Bone() = default;
  virtual BoneSample eval(const V3& p) const = 0;
  // Signed distance to the air cavities this bone encloses (sinuses); soft tissue there is air.
  virtual double air(const V3&) const { return kInf; }
  Box3 box;  // world box containing the outer surface
};

// A bone built in its own frame and placed in the world by a similarity (Femur, Skull): its local
// bounding box, the placement and the world box that follows from them.
class PlacedBone : public Bone {
 public:
  // world = origin + scale * R * local (R orthogonal; a mirror is allowed).
  void place(const M3& R, double scale, const V3& origin) {
    R_ = R;
    scale_ = scale;
    origin_ = origin;
    to_local_ = R.transpose() / scale;
    box = Box3();
    for (int c = 0; c < 8; ++c) {
      const V3 corner((c & 1) ? local_box_.hi.x() : local_box_.lo.x(),
                      (c & 2) ? local_box_.hi.y() : local_box_.lo.y(),
                      (c & 4) ? local_box_.hi.z() : local_box_.lo.z());
      box.add(to_world(corner), 0.0);
    }
  }
  V3 to_world(const V3& q) const { return origin_ + scale_ * mul(R_, q); }
  V3 dir_to_world(const V3& v) const { return mul(R_, v); }

 protected:
  Box3 local_box_;
  M3 R_ = M3::Identity(), to_local_ = M3::Identity();
  double scale_ = 1;
  V3 origin_ = V3::Zero();
};

// A femur in its own frame: shaft axis along +z (proximal), +x medial, -y anterior (LPS for a
// right femur). Millimetres for a 256 mm field of view.
struct FemurShape {
  double bow = 0, lateral_bow = 0, bow_half_length = 60;  // anterior / lateral bow of the shaft
  std::vector<std::pair<double, double>> shaft;           // (z, radius), distal to proximal
  double neck_z = 39, neck_angle_deg = 130, anteversion_deg = 12, neck_length = 45;
  double neck_r_base = 15, neck_r_head = 12, head_r = 22;
  V3 gt_c{-10, 3, 56}, gt_r{13, 15, 18};  // greater trochanter
  V3 lt_c{10, 10, 25}, lt_r{7, 7, 9};     // lesser trochanter
  bool condyles = true;
  V3 meta_c{0, 2, -62}, meta_r{30, 20, 20};   // distal metaphysis
  V3 med_c{17, 8, -70}, med_r{13, 23, 19};    // medial condyle
  V3 lat_c{-16, 8, -69}, lat_r{14, 23, 18};   // lateral condyle
  double t_shaft = 5, t_end = 2;              // cortical thickness, diaphysis and ends
  double t_lo_end = -50, t_lo_full = -25, t_hi_full = 25, t_hi_end = 42;
};

class Femur final : public PlacedBone {
 public:
  explicit Femur(const FemurShape& s) : s_(s) {
    for (size_t n = 0; n + 1 < s.shaft.size(); ++n)
      shaft_.emplace_back(axis(s.shaft[n].first), axis(s.shaft[n + 1].first), s.shaft[n].second,
                          s.shaft[n + 1].second);
    const double th = radians(180.0 - s.neck_angle_deg), av = radians(s.anteversion_deg);
    neck_dir_ = V3(det_sin(th) * det_cos(av), -det_sin(th) * det_sin(av), det_cos(th));
    const V3 n0 = axis(s.neck_z);
    head_ = Sphere{n0 + s.neck_length * neck_dir_, s.head_r};
    neck_ = RoundCone(n0, head_.c, s.neck_r_base, s.neck_r_head);
    gt_ = Ellipsoid(s.gt_c, s.gt_r);
    lt_ = Ellipsoid(s.lt_c, s.lt_r);
    if (s.condyles) {
      meta_ = Ellipsoid(s.meta_c, s.meta_r);
      med_ = Ellipsoid(s.med_c, s.med_r);
      lat_ = Ellipsoid(s.lat_c, s.lat_r);
    }
    for (const auto& c : shaft_) c.bound(local_box_);
    neck_.bound(local_box_);
    head_.bound(local_box_);
    gt_.bound(local_box_);
    lt_.bound(local_box_);
    if (s.condyles) {
      meta_.bound(local_box_);
      med_.bound(local_box_);
      lat_.bound(local_box_);
    }
    local_box_.grow(10.0 / 4.0 + 0.5);  // smooth-min growth (largest k is 10)
    place(M3::Identity(), 1.0, V3::Zero());
  }

  V3 head_local() const { return head_.c; }
  V3 neck_dir_local() const { return neck_dir_; }
  V3 axis(double z) const {
    const double u = z / s_.bow_half_length;
    const double w = std::max(0.0, 1.0 - u * u);
    return V3(s_.lateral_bow * w, -s_.bow * w, z);
  }

  BoneSample eval(const V3& p) const override {
    const V3 q = mul(to_local_, p - origin_);
    double d = shaft_[0].eval(q);
    for (size_t n = 1; n < shaft_.size(); ++n) d = std::min(d, shaft_[n].eval(q));
    d = smin(d, neck_.eval(q), 7.0);
    d = smin(d, head_.eval(q), 3.0);
    d = smin(d, gt_.eval(q), 8.0);
    d = smin(d, lt_.eval(q), 5.0);
    if (s_.condyles) {
      d = smin(d, meta_.eval(q), 10.0);
      d = smin(d, med_.eval(q), 5.0);
      d = smin(d, lat_.eval(q), 5.0);
    }
    const double w = smoothstep(s_.t_lo_end, s_.t_lo_full, q.z()) *
                     (1.0 - smoothstep(s_.t_hi_full, s_.t_hi_end, q.z()));
    const double t = s_.t_end + (s_.t_shaft - s_.t_end) * w;
    return {d * scale_, t * scale_};
  }

 private:
  FemurShape s_;
  std::vector<RoundCone> shaft_;
  V3 neck_dir_;
  Sphere head_;
  RoundCone neck_;
  Ellipsoid gt_, lt_, meta_, med_, lat_;
};

// One side of the pelvis (ilium, acetabulum, pubis, ischium), world frame.
struct Hemipelvis {
  Ellipsoid bowl, outline;  // ilium = shell of `bowl` cut to `outline`
  double half_thick = 4.5;
  Sphere acetabulum;        // bone block around the cup
  RoundCone sup_ramus, inf_ramus, ischium;
  Ellipsoid pubic_body, tuberosity;
  Box3 box;

  void bound() {
    box = Box3();
    outline.bound(box);
    acetabulum.bound(box);
    sup_ramus.bound(box);
    inf_ramus.bound(box);
    ischium.bound(box);
    pubic_body.bound(box);
    tuberosity.bound(box);
    box.grow(10.0 / 4.0 + 0.5);
  }
  double eval(const V3& p) const {
    const double wing = smax(std::abs(bowl.eval(p)) - half_thick, outline.eval(p), 6.0);
    double d = smin(wing, acetabulum.eval(p), 10.0);
    d = smin(d, sup_ramus.eval(p), 6.0);
    d = smin(d, pubic_body.eval(p), 5.0);
    d = smin(d, inf_ramus.eval(p), 5.0);
    d = smin(d, tuberosity.eval(p), 6.0);
    d = smin(d, ischium.eval(p), 6.0);
    return d;
  }
};

class Pelvis final : public Bone {
 public:
  TaperedPlate sacrum;
  RoundCone coccyx;
  Ellipsoid ala[2];
  Hemipelvis side[2];
  Sphere cup[2];
  double thickness = 2.0;
  double cull = 10.0;  // hemipelvis culling distance (set from the supersampling band)

  void bound() {
    box = Box3();
    sacrum.bound(box);
    coccyx.bound(box);
    for (int s = 0; s < 2; ++s) {
      ala[s].bound(box);
      side[s].bound();
      box.add(side[s].box);
    }
    box.grow(6.0 / 4.0 + 0.5);
  }
  BoneSample eval(const V3& p) const override {
    double d = smin(sacrum.eval(p), coccyx.eval(p), 4.0);
    for (int s = 0; s < 2; ++s) d = smin(d, ala[s].eval(p), 8.0);
    for (int s = 0; s < 2; ++s) {
      // Far from a hemipelvis its box distance is a lower bound that leaves the result (sign and
      // nearness) unchanged; it saves most of the work.
      const double bd = side[s].box.distance(p);
      d = smin(d, bd > cull ? bd : side[s].eval(p), 6.0);
    }
    for (int s = 0; s < 2; ++s) d = smax(d, -cup[s].eval(p), 2.0);
    return {d, thickness};
  }
};

class Vertebra final : public Bone {
 public:
  EllipticCylinder body;
  double thickness = 1.5;
  void bound() {
    box = Box3();
    body.bound(box);
  }
  BoneSample eval(const V3& p) const override { return {body.eval(p), thickness}; }
};

// A skull in its own frame (LPS: +x left, +y posterior, +z superior), millimetres for a 256 mm
// field of view: a thin cranial shell (outer and inner tables of cortical bone, diploe between
// where the shell is thick enough) around the brain, a facial skeleton hollowed by the orbits, the
// nasal cavity and the paranasal sinuses (air), the zygomatic arches, the petrous ridges of the
// skull base, the foramen magnum, a mandible, an upper cervical vertebra below, and a burr hole on
// one side, so that no rotation maps the head onto itself.
struct SkullShape {
  V3 cranium_c{0, 5, 35}, cranium_r{74, 90, 62};
  double shell_thick = 7.0, shell_thin = 2.5;  // vertex/frontal/occipital and temporal thickness
  V3 face_c{0, -70, -25}, face_r{46, 26, 42};
  V3 orbit_c{32, -82, 0}, orbit_r{17, 24, 16};  // the left orbit; the right one mirrored
  V3 maxillary_c{24, -64, -32}, maxillary_r{15, 19, 16};
  double maxillary_right_scale = 1.0;            // the sinuses differ a little side to side
  V3 nasal_c{0, -74, -24}, nasal_r{10, 26, 23};
  V3 frontal_c{0, -82, 32}, frontal_r{26, 12, 17}, frontal_sinus_r{15, 5, 9};
  V3 sphenoid_c{0, -38, -6}, sphenoid_r{19, 17, 15}, sphenoid_sinus_r{11, 10, 10};
  V3 foramen_c{0, 28, -22};
  double foramen_r = 16;
  double jaw_open_deg = 3;                       // the mandible's rotation about its condyles
  V3 burr_dir{0.55, 0.25, 0.8};                  // a burr hole through the shell in this direction
  double burr_r = 7;
  double tables = 2.0;                           // cortical table thickness
};

class Skull final : public PlacedBone {
 public:
  explicit Skull(const SkullShape& s) : s_(s) {
    cranium_ = Ellipsoid(s.cranium_c, s.cranium_r);
    face_ = Ellipsoid(s.face_c, s.face_r);
    frontal_ = Ellipsoid(s.frontal_c, s.frontal_r);
    sphenoid_ = Ellipsoid(s.sphenoid_c, s.sphenoid_r);
    const V3 mirror(-1, 1, 1);
    orbit_[0] = Ellipsoid(s.orbit_c, s.orbit_r);
    orbit_[1] = Ellipsoid(s.orbit_c.cwiseProduct(mirror), s.orbit_r);
    air_.push_back(Ellipsoid(s.maxillary_c, s.maxillary_r));
    air_.push_back(Ellipsoid(s.maxillary_c.cwiseProduct(mirror), s.maxillary_r * s.maxillary_right_scale));
    air_.push_back(Ellipsoid(s.nasal_c, s.nasal_r));
    air_.push_back(Ellipsoid(s.frontal_c + V3(0, -1, 0), s.frontal_sinus_r));
    air_.push_back(Ellipsoid(s.sphenoid_c, s.sphenoid_sinus_r));
    for (int side = 0; side < 2; ++side) {
      const double sg = side == 0 ? 1.0 : -1.0;
      zygoma_[side] = RoundCone(V3(sg * 44, -72, -8), V3(sg * 64, -12, -12), 5, 4);
      petrous_[side] = RoundCone(V3(sg * 58, 12, -4), V3(sg * 14, -14, -10), 9, 5);
    }
    // The mandible: a U of round cones from the chin back to the angles, then up the rami to the
    // condyles below the skull base, rotated about the condyles by the jaw opening.
    const V3 condyle(48, -8, -24);
    const M3 open = rot_x(-s.jaw_open_deg);
    const auto jaw = [&](const V3& p) {
      const V3 pivot = condyle.cwiseProduct(V3(0, 1, 1));
      return V3(pivot + mul(open, p - pivot));
    };
    chin_ = Ellipsoid(jaw(V3(0, -90, -84)), V3(15, 9, 12));
    for (int side = 0; side < 2; ++side) {
      const double sg = side == 0 ? 1.0 : -1.0;
      mandible_body_[side] = RoundCone(jaw(V3(0, -90, -82)), jaw(V3(sg * 46, -30, -80)), 8, 7);
      ramus_[side] = RoundCone(jaw(V3(sg * 46, -30, -80)), jaw(condyle.cwiseProduct(V3(sg, 1, 1))), 7, 6);
      upper_arch_[side] = RoundCone(V3(0, -94, -58), V3(sg * 36, -52, -56), 7, 7);
    }
    foramen_.c = s.foramen_c;
    foramen_.rx = foramen_.ry = s.foramen_r;
    foramen_.half_h = 20;
    foramen_.round = 2;
    const V3 bd = unit(s.burr_dir);
    // The burr hole's axis from the cranium centre through the shell where burr_dir points.
    burr_.c = s.cranium_c + bd / len(bd.cwiseQuotient(s.cranium_r));
    burr_.rx = burr_.ry = s.burr_r;
    burr_.half_h = 14;
    burr_.round = 1;
    burr_.to_local = frame_with_z(bd).transpose();
    cervical_.c = V3(0, 24, -50);
    cervical_.rx = 11;
    cervical_.ry = 10;
    cervical_.half_h = 13;
    cervical_.round = 3;
    scalp_ = Ellipsoid(s.cranium_c, s.cranium_r + V3::Constant(9));
    cheeks_ = Ellipsoid(V3(0, -52, -50), V3(62, 56, 50));
    neck_ = Ellipsoid(V3(0, 14, -110), V3(56, 54, 70));

    foramen_.bound(foramen_box_);
    burr_.bound(burr_box_);
    cervical_.bound(cervical_box_);
    sphenoid_.bound(base_box_);
    for (const RoundCone& r : petrous_) r.bound(base_box_);
    frontal_.bound(face_box_);
    face_.bound(face_box_);
    for (int side = 0; side < 2; ++side) {
      zygoma_[side].bound(face_box_);
      upper_arch_[side].bound(face_box_);
      orbit_[side].bound(face_box_);
    }
    for (const Ellipsoid& a : air_) a.bound(air_box_);
    chin_.bound(jaw_box_);
    for (int side = 0; side < 2; ++side) {
      mandible_body_[side].bound(jaw_box_);
      ramus_[side].bound(jaw_box_);
    }
    cranium_.bound(local_box_);
    face_.bound(local_box_);
    chin_.bound(local_box_);
    for (int side = 0; side < 2; ++side) {
      zygoma_[side].bound(local_box_);
      mandible_body_[side].bound(local_box_);
      ramus_[side].bound(local_box_);
    }
    cervical_.bound(local_box_);
    local_box_.grow(8.0 / 4.0 + 0.5);
    place(M3::Identity(), 1.0, V3::Zero());
  }

  // The body's envelope (world mm, negative inside): the scalp over the cranium, the soft tissue
  // of the face and the neck, and at least `cover` mm of soft tissue over every bone.
  // Deep inside the ellipsoids (beyond `deep` mm) the bones are not evaluated: the point is inside
  // either way and farther than `deep` from the envelope (callers pass their supersampling band).
  double envelope(const V3& p, double cover, double deep) const {
    const V3 q = mul(to_local_, p - origin_);
    double d = scalp_.eval(q);
    d = smin(d, cheeks_.eval(q), 20.0);
    d = smin(d, neck_.eval(q), 20.0);
    d *= scale_;
    if (d < -deep) return d;
    return std::min(d, eval(p).d - cover * scale_);
  }

  BoneSample eval(const V3& p) const override {
    const V3 q = mul(to_local_, p - origin_);
    // The cranial shell: thick (tables and diploe) over the vault, thin at the temples.
    const V3 qc = q - s_.cranium_c;
    const double lateral = std::abs(qc.x()) / s_.cranium_r.x();
    const double T = s_.shell_thick - (s_.shell_thick - s_.shell_thin) * smoothstep(0.6, 0.95, lateral);
    const double outer = cranium_.eval(q);
    double d = std::abs(outer + 0.5 * T) - 0.5 * T;
    // Parts far from p (by their boxes, with a margin beyond every blend radius) are skipped:
    // they would change neither the sign nor, within the supersampling band, the distance.
    if (base_box_.distance(q) < kSkip) {
      d = smin(d, sphenoid_.eval(q), 6.0);
      for (const RoundCone& r : petrous_) d = smin(d, r.eval(q), 5.0);
    }
    if (face_box_.distance(q) < kSkip) {
      d = smin(d, frontal_.eval(q), 6.0);
      d = smin(d, face_.eval(q), 8.0);
      for (int side = 0; side < 2; ++side) {
        d = smin(d, zygoma_[side].eval(q), 4.0);
        d = smin(d, upper_arch_[side].eval(q), 4.0);
      }
      // Openings and cavities: orbits (soft tissue), sinuses and nasal cavity (air).
      for (const Ellipsoid& o : orbit_) d = smax(d, -o.eval(q), 3.0);
    }
    if (air_box_.distance(q) < kSkip)
      for (const Ellipsoid& a : air_) d = smax(d, -a.eval(q), 2.0);
    // The foramen magnum and the burr hole.
    if (foramen_box_.distance(q) < kSkip) d = smax(d, -foramen_.eval(q), 2.0);
    if (burr_box_.distance(q) < kSkip) d = smax(d, -burr_.eval(q), 1.0);
    // The mandible and the vertebra are separate bones (joint spaces around them).
    if (jaw_box_.distance(q) < kSkip) {
      double jaw = smin(chin_.eval(q), mandible_body_[0].eval(q), 6.0);
      jaw = smin(jaw, mandible_body_[1].eval(q), 6.0);
      for (const RoundCone& r : ramus_) jaw = smin(jaw, r.eval(q), 5.0);
      d = std::min(d, jaw);
    }
    if (cervical_box_.distance(q) < kSkip) d = std::min(d, cervical_.eval(q));
    return {d * scale_, s_.tables * scale_};
  }

  double air(const V3& p) const override {
    const V3 q = mul(to_local_, p - origin_);
    if (air_box_.distance(q) >= kSkip) return kInf;
    double d = kInf;
    for (const Ellipsoid& a : air_) d = std::min(d, a.eval(q));
    return d * scale_;
  }

 private:
  // An orthonormal frame whose third axis is z (columns).
  static M3 frame_with_z(const V3& z) {
    const V3 a = std::abs(z.x()) < 0.9 ? V3(1, 0, 0) : V3(0, 1, 0);
    const V3 x = unit(a - dot(a, z) * z);
    const V3 y(z.y() * x.z() - z.z() * x.y(), z.z() * x.x() - z.x() * x.z(), z.x() * x.y() - z.y() * x.x());
    M3 m;
    m.col(0) = x;
    m.col(1) = y;
    m.col(2) = z;
    return m;
  }

  static constexpr double kSkip = 24.0;  // mm beyond a part's box: more than any blend or band
  SkullShape s_;
  Box3 base_box_, face_box_, air_box_, jaw_box_, foramen_box_, burr_box_, cervical_box_;
  Ellipsoid cranium_, face_, frontal_, sphenoid_, chin_, orbit_[2], scalp_, cheeks_, neck_;
  std::vector<Ellipsoid> air_;
  RoundCone zygoma_[2], petrous_[2], mandible_body_[2], ramus_[2], upper_arch_[2];
  EllipticCylinder foramen_, burr_, cervical_;
};

// A screw-like rod: a head at `head` and a threaded shank running along `dir`.
struct Screw {
  V3 head = V3::Zero(), dir = V3::UnitZ();
  double length = 60, radius = 3, head_radius = 5.5, head_length = 4, pitch = 2.5, thread = 0.45;
  Sphere bounds;

  static double capped(double rho, double along, double a0, double a1, double r) {
    const double dx = rho - r, dy = std::max(a0 - along, along - a1);
    const double ox = std::max(dx, 0.0), oy = std::max(dy, 0.0);
    return std::min(std::max(dx, dy), 0.0) + std::sqrt(ox * ox + oy * oy);
  }
  double eval(const V3& p) const {
    const V3 v = p - head;
    const double along = dot(v, dir);
    const V3 radial = v - along * dir;
    const double rho = len(radial);
    const double taper = length - 2.0 * radius;  // the tip narrows over its last 2 radii
    double r = radius;
    if (along > taper) r = radius - (radius - 0.35 * radius) * std::min(1.0, (along - taper) / (length - taper));
    const double x = along / pitch;
    const double tri = 2.0 * std::abs(x - std::floor(x) - 0.5);  // thread profile, 0..1
    r -= thread * tri;
    const double shank = capped(rho, along, head_length, length, r);
    const double cap = capped(rho, along, 0.0, head_length, head_radius);
    return std::min(shank, cap);
  }
};

// ---------------------------------------------------------------------------------------------
// The scene: body, bones, fiducials, metal, in priority order metal > fiducial > bone > tissue.

struct Scene {
  EllipticCylinder body;
  std::function<double(const V3&)> envelope;  // replaces `body` when set (the head's outline)
  std::vector<std::unique_ptr<Bone>> bones;
  std::vector<V3> fiducials;
  double fiducial_r = 0;
  std::optional<Screw> screw;
  double cull = 1;  // bones farther than this from their box are skipped

  double body_distance(const V3& p) const { return envelope ? envelope(p) : body.eval(p); }

  double bone_distance(const V3& p) const {
    double d = kInf;
    for (const auto& b : bones) d = std::min(d, b->eval(p).d);
    return d;
  }
  V3 bone_normal(const V3& p, double eps) const {
    V3 g;
    for (int a = 0; a < 3; ++a) {
      V3 e = V3::Zero();
      e[a] = eps;
      g[a] = bone_distance(p + e) - bone_distance(p - e);
    }
    const double n = len(g);
    return n > 0 ? V3(g / n) : V3(V3::UnitZ());
  }

  // HU at p and (via `near`) a distance below which a tissue interface may lie.
  double value(const V3& p, double* near) const {
    const double db = body_distance(p);
    double nr = std::abs(db);
    if (db >= 0) {  // everything else lies inside the body
      if (near) *near = nr;
      return kAirHU;
    }
    double v = kSoftTissueHU, deepest = 0, air = kInf;
    for (const auto& b : bones) {
      if (b->box.distance(p) > cull) continue;
      air = std::min(air, b->air(p));
      const BoneSample s = b->eval(p);
      nr = std::min(nr, std::min(std::abs(s.d), std::abs(s.d + s.t)));
      if (s.d < deepest) {
        deepest = s.d;
        v = s.d > -s.t ? kCorticalHU : kMarrowHU;
      }
    }
    if (air < kInf) nr = std::min(nr, std::abs(air));
    if (deepest == 0 && air < 0) v = kAirHU;
    bool in_fiducial = false;
    for (const V3& c : fiducials) {
      const double d = len(p - c) - fiducial_r;
      nr = std::min(nr, std::abs(d));
      in_fiducial = in_fiducial || d < 0;
    }
    if (in_fiducial) v = kFiducialHU;
    if (screw && screw->bounds.eval(p) < cull) {
      const double d = screw->eval(p);
      nr = std::min(nr, std::abs(d));
      if (d < 0) v = kMetalHU;
    }
    if (near) *near = nr;
    return v;
  }
};

// What a kind-specific builder hands to the common code.
struct Layout {
  V3 screw_target = V3::Zero();   // inside the bone
  V3 screw_outward = V3::UnitX();  // the screw enters from this side
  std::vector<V3> anchors;         // candidate fiducial sites near the bone surface
};

// ---------------------------------------------------------------------------------------------
// Femur phantom: a right femur, head medial (+x), proximal up (+z), anterior bow towards -y.

Layout build_femur(Random& rng, double g, Scene& scene) {
  FemurShape s;
  s.bow = rng.range(3.0, 7.0);
  s.lateral_bow = rng.range(-1.5, 1.5);
  const double rs = rng.vary(1.0, 0.05);
  s.shaft = {{-58, 18.0 * rs}, {-42, 15.5 * rs}, {-22, 13.5 * rs}, {0, 13.0 * rs},
             {22, 13.5 * rs},  {36, 15.5 * rs},  {52, 16.5 * rs}};
  s.neck_z = 39;
  s.neck_angle_deg = rng.range(126.0, 134.0);
  s.anteversion_deg = rng.range(8.0, 16.0);
  s.neck_length = rng.vary(45.0, 0.05);
  s.head_r = rng.vary(22.0, 0.05);
  s.neck_r_base = 15.0 * rs;
  s.neck_r_head = 12.0 * rs;
  s.gt_r = V3(13, 15, 18) * rng.vary(1.0, 0.05);
  s.lt_r = V3(7, 7, 9) * rng.vary(1.0, 0.05);
  const double cw = rng.vary(1.0, 0.05);
  s.meta_r = V3(30 * cw, 20, 20);
  s.med_c = V3(17 * cw, 8, -70);
  s.med_r = V3(13, 23, 19) * cw;
  s.lat_c = V3(-16 * cw, 8, -69);
  s.lat_r = V3(14, 23, 18) * cw;
  s.t_shaft = rng.range(4.5, 5.5);
  s.t_end = 2.0;

  const double scale = g * rng.vary(1.0, 0.03);
  const double rz = rng.range(-4.0, 4.0), ry = rng.range(-2.0, 2.0), rx = rng.range(-2.0, 2.0);
  const M3 R = matmul(rot_z(rz), matmul(rot_y(ry), rot_x(rx)));
  const V3 origin = V3(-13.0, 0.0, 0.0) * g;

  auto femur = std::make_unique<Femur>(s);
  femur->place(R, scale, origin);

  scene.body.c = V3(0, 2, 0) * g;
  scene.body.rx = 84 * g;
  scene.body.ry = 74 * g;
  scene.body.half_h = 112 * g;
  scene.body.round = 14 * g;

  Layout lay;
  // A lag screw from the lateral cortex below the greater trochanter up the neck into the head.
  const V3 jitter = rng.vec(-0.06, 0.06);
  lay.screw_target = femur->to_world(femur->head_local() + V3(0, 0, -3));
  lay.screw_outward = unit(femur->dir_to_world(-femur->neck_dir_local()) + jitter);
  const V3 n0 = femur->axis(s.neck_z);
  const V3 local_anchors[] = {
      {-16, -3, -20}, {0, -18, 10},        {16, 0, -35},         {-26, 3, 62},      {32, 8, -68},
      {-32, 8, -68},  {0, -22, -50},        n0 + V3(18, -16, 14), {0, 16, -5},       {-15, 0, 20}};
  for (const V3& a : local_anchors) lay.anchors.push_back(femur->to_world(a));
  scene.bones.push_back(std::move(femur));
  return lay;
}

// ---------------------------------------------------------------------------------------------
// Pelvis phantom: sacrum, two hemipelves closing the ring at the pubic symphysis, an L5 body,
// and both proximal femurs with their heads in the acetabula.

Layout build_pelvis(Random& rng, double g, Scene& scene) {
  const double G = g * rng.vary(1.0, 0.03);
  const double wide = rng.vary(1.0, 0.04);     // x scale of the hemipelves
  const double tilt = rng.range(20.0, 30.0);   // sacral tilt, degrees
  const double wing_t = rng.range(4.0, 5.0);   // half thickness of the iliac wings
  const double acetab_dx = rng.range(-2.0, 2.0);
  const double acetab_dy = rng.range(-2.0, 2.0);
  const V3 acetab(48.0 * wide + acetab_dx, -5.0 + acetab_dy, -15.0);
  auto P = [G](double x, double y, double z) { return V3(x * G, y * G, z * G); };

  auto pelvis = std::make_unique<Pelvis>();
  pelvis->thickness = 2.0 * G;
  // The sacrum: a wedge-shaped plate, its top anterior, concave in front, and the coccyx.
  const double st = det_sin(radians(tilt)), ct = det_cos(radians(tilt));
  TaperedPlate& sac = pelvis->sacrum;
  sac.c = P(0, 26, 24);
  sac.to_local = rot_x(tilt).transpose();  // local +z = (0, -sin, cos): up and anterior
  sac.half_len = 32 * G;
  sac.top_hx = 24 * G;
  sac.bottom_hx = 8 * G;
  sac.top_hy = 13 * G;
  sac.bottom_hy = 6 * G;
  sac.bow = 5 * G;
  sac.round = 4 * G;
  const V3 sac_bottom = sac.c + sac.half_len * V3(0, st, -ct);
  pelvis->coccyx = RoundCone(sac_bottom, sac_bottom + V3(0, -3, -14) * G, 5 * G, 3 * G);
  const double bowl_r = rng.vary(1.0, 0.04);
  for (int s = 0; s < 2; ++s) {
    const double sg = s == 0 ? -1.0 : 1.0;  // s = 0: right (-x), s = 1: left (+x)
    pelvis->ala[s] = Ellipsoid(P(sg * 24, 26, 38), V3(17, 13, 16) * G);
    Hemipelvis& h = pelvis->side[s];
    h.bowl = Ellipsoid(P(0, -15, 90), V3(90 * wide * bowl_r, 55 * bowl_r, 150) * G);
    h.outline = Ellipsoid(P(sg * 62 * wide, 5, 10), V3(48 * wide, 55, 50) * G);
    h.half_thick = wing_t * G;
    const V3 A(sg * acetab.x() * G, acetab.y() * G, acetab.z() * G);
    const V3 cup_axis = unit(V3(sg * 0.68, -0.26, -0.68));
    h.acetabulum = Sphere{A - 10 * G * cup_axis, 26 * G};
    h.sup_ramus = RoundCone(A + V3(-sg * 12, -14, -6) * G, P(sg * 11, -42, -42), 9 * G, 7 * G);
    h.pubic_body = Ellipsoid(P(sg * 12, -40, -48), V3(9, 8, 14) * G);
    h.inf_ramus = RoundCone(P(sg * 13, -36, -58), P(sg * 38 * wide, 8, -62), 6 * G, 7 * G);
    h.tuberosity = Ellipsoid(P(sg * 38 * wide, 8, -62), V3(11, 13, 15) * G);
    h.ischium = RoundCone(P(sg * 38 * wide, 8, -62), A + V3(-sg * 4, 14, -12) * G, 9 * G, 13 * G);
    pelvis->cup[s] = Sphere{A, 22.5 * G};
  }
  pelvis->cull = scene.cull + 10.0 * G;
  pelvis->bound();

  auto l5 = std::make_unique<Vertebra>();
  l5->body.c = P(0, 8, 66);
  l5->body.rx = 24 * G;
  l5->body.ry = 17 * G;
  l5->body.half_h = 10 * G;
  l5->body.round = 3 * G;
  l5->body.to_local = rot_x(-8).transpose();
  l5->thickness = 1.5 * G;
  l5->bound();

  // Proximal femurs, heads centred in the cups.
  FemurShape f;
  f.bow = 0;
  f.lateral_bow = 0;
  f.shaft = {{-45, 11.5}, {-20, 11.5}, {0, 13}, {14, 14}};
  f.neck_z = 0;
  f.neck_angle_deg = rng.range(126.0, 134.0);
  f.anteversion_deg = rng.range(8.0, 16.0);
  f.neck_length = 36;
  f.neck_r_base = 11.5;
  f.neck_r_head = 9.5;
  f.head_r = rng.vary(20.0, 0.04);
  f.gt_c = V3(-8, 3, 16);
  f.gt_r = V3(9.5, 12, 13);
  f.lt_c = V3(9, 9, -13);
  f.lt_r = V3(6, 6, 8);
  f.condyles = false;
  f.t_shaft = 4.0;
  f.t_end = 1.8;
  f.t_lo_end = -400;
  f.t_lo_full = -300;
  f.t_hi_full = -15;
  f.t_hi_end = 5;
  V3 greater_trochanter[2];
  for (int s = 0; s < 2; ++s) {
    const double sg = s == 0 ? -1.0 : 1.0;
    auto femur = std::make_unique<Femur>(f);
    M3 R = M3::Identity();
    if (sg > 0) R(0, 0) = -1;  // the left femur is the mirror image; medial is -x
    const V3 A(sg * acetab.x() * G, acetab.y() * G, acetab.z() * G);
    femur->place(R, G, A - G * mul(R, femur->head_local()));
    greater_trochanter[s] = femur->to_world(f.gt_c + V3(-12, 0, 4));
    scene.bones.push_back(std::move(femur));
  }

  scene.body.c = P(0, 5, 0);
  scene.body.rx = 112 * g;
  scene.body.ry = 82 * g;
  scene.body.half_h = 112 * g;
  scene.body.round = 15 * g;

  Layout lay;
  // An iliosacral screw from the outer right ilium into the S1 body.
  lay.screw_target = P(0, 16, 42);
  const double screw_dy = rng.range(-0.06, 0.06);
  const double screw_dz = rng.range(-0.06, 0.06);
  lay.screw_outward = unit(V3(-1.0, 0.12 + screw_dy, -0.08 + screw_dz));
  lay.anchors = {P(-62 * wide, 5, 62), P(62 * wide, 5, 62), P(-80 * wide, -35, 22), P(80 * wide, -35, 22),
                 P(-18, -52, -46),     P(18, -52, -46),     P(-40 * wide, 18, -80), P(40 * wide, 18, -80),
                 P(0, 52, 20),         greater_trochanter[0], greater_trochanter[1]};
  scene.bones.push_back(std::move(pelvis));
  scene.bones.push_back(std::move(l5));
  return lay;
}

// ---------------------------------------------------------------------------------------------
// Head phantom: a skull whose thin shell surrounds every ray through the brain (the case of a
// head CT), face forward (-y), vertex up (+z).

Layout build_head(Random& rng, double g, Scene& scene) {
  SkullShape s;
  s.cranium_r = V3(74, 90, 62) * rng.vary(1.0, 0.03);
  s.shell_thick = rng.range(6.0, 7.0);
  s.shell_thin = rng.range(2.2, 3.0);
  s.maxillary_right_scale = rng.range(0.85, 1.1);
  s.jaw_open_deg = rng.range(0.0, 8.0);
  const double burr_side = rng.uniform() < 0.5 ? -1.0 : 1.0;
  s.burr_dir = V3(burr_side * rng.range(0.4, 0.7), rng.range(-0.3, 0.3), rng.range(0.6, 0.9));
  s.burr_r = rng.range(6.0, 8.0);

  const double scale = g * rng.vary(1.0, 0.03);
  const double rz = rng.range(-4.0, 4.0), ry = rng.range(-3.0, 3.0), rx = rng.range(-5.0, 5.0);
  const M3 R = matmul(rot_z(rz), matmul(rot_y(ry), rot_x(rx)));
  auto skull = std::make_unique<Skull>(s);
  skull->place(R, scale, V3::Zero());
  const Skull* k = skull.get();
  const double deep = scene.cull + 1.0;
  scene.envelope = [k, deep](const V3& p) { return k->envelope(p, 9.0, deep); };

  Layout lay;
  // A screw from the lateral side into the left angle of the mandible (a fixation screw).
  lay.screw_target = skull->to_world(V3(44, -34, -80));
  lay.screw_outward = unit(skull->dir_to_world(V3(1, 0.1, 0.05)) + rng.vec(-0.06, 0.06));
  const V3 local_anchors[] = {{0, -100, 40},   {-50, -60, 55},  {50, -60, 55},  {-82, 10, 30},  {82, 10, 30},
                              {0, 100, 40},    {0, 10, 102},    {-60, -75, -15}, {60, -75, -15}, {0, -104, -88},
                              {-55, -40, -90}, {55, -40, -90},  {-60, 45, 75},   {60, 45, 75},   {0, 65, 88},
                              {-75, -35, 45},  {75, -35, 45},   {0, -55, 90}};
  for (const V3& a : local_anchors) lay.anchors.push_back(skull->to_world(a));
  scene.bones.push_back(std::move(skull));
  return lay;
}

// The first point on the segment from `from` to `to` where the bone begins (fixed steps).
V3 first_bone_hit(const Scene& scene, const V3& from, const V3& to, double step) {
  const V3 d = to - from;
  const int n = std::max(1, int(std::ceil(len(d) / step)));
  for (int i = 0; i <= n; ++i) {
    const V3 p = from + d * (double(i) / n);
    if (scene.bone_distance(p) <= 0) return p;
  }
  return to;
}

double segment_distance(const V3& p, const V3& a, const V3& b) {
  const V3 ab = b - a;
  const double t = std::clamp(dot(p - a, ab) / dot(ab, ab), 0.0, 1.0);
  return len(p - (a + t * ab));
}

}  // namespace

PhantomKind parse_phantom_kind(const std::string& name) {
  if (name == "femur") return PhantomKind::femur;
  if (name == "pelvis") return PhantomKind::pelvis;
  if (name == "head") return PhantomKind::head;
  throw_input_error("--kind " + name, "unknown phantom kind (femur, pelvis, head)");
}

Phantom make_phantom(const PhantomParams& params) {
  if (params.size < 8 || params.size > 2048)
    throw_input_error("phantom size " + std::to_string(params.size), "must be 8 to 2048 voxels");
  if (!std::isfinite(params.fov_mm) || params.fov_mm <= 0)
    throw_input_error("phantom field of view " + std::to_string(params.fov_mm), "must be positive");

  const int n = params.size;
  const double h = params.fov_mm / n;  // isotropic spacing
  const double g = params.fov_mm / 256.0;  // anatomy scale
  const double o = -0.5 * (n - 1) * h;
  const double band = std::sqrt(3.0) * h;  // supersample within a voxel diagonal of an interface

  Phantom ph;
  VolumeGeometry& geo = ph.hu.geometry;
  geo.size = Eigen::Vector3i(n, n, n);
  geo.spacing = V3(h, h, h);
  geo.origin = V3(o, o, o);
  geo.direction = M3::Identity();

  // All random choices, in a fixed order: shape, screw, fiducials.
  Random rng(params.seed);
  Scene scene;
  scene.cull = band + 1.0;
  const Layout lay = params.kind == PhantomKind::femur    ? build_femur(rng, g, scene)
                     : params.kind == PhantomKind::pelvis ? build_pelvis(rng, g, scene)
                                                          : build_head(rng, g, scene);

  if (params.metal_object) {
    Screw sc;
    sc.length = 60 * g;
    sc.radius = 3 * g;
    sc.head_radius = 5.5 * g;
    sc.head_length = 4 * g;
    sc.pitch = 2.5 * g;
    sc.thread = 0.45 * g;
    const V3 entry = first_bone_hit(scene, lay.screw_target + 150.0 * g * lay.screw_outward, lay.screw_target,
                                    0.2 * g);
    sc.head = entry + sc.head_length * lay.screw_outward;
    sc.dir = -lay.screw_outward;
    sc.bounds = Sphere{sc.head + 0.5 * sc.length * sc.dir, 0.5 * sc.length + sc.head_radius + 1.0};
    scene.screw = sc;
  }

  if (params.fiducials) {
    const double r = 2.0 * g;
    const int want = 4 + rng.below(3);
    std::vector<int> order(lay.anchors.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = int(i);
    for (int i = int(order.size()) - 1; i > 0; --i) std::swap(order[i], order[rng.below(i + 1)]);
    std::vector<V3> jitter(order.size());
    for (auto& j : jitter) j = rng.vec(-6.0, 6.0) * g;
    for (int idx : order) {
      if (int(scene.fiducials.size()) == want) break;
      V3 p = lay.anchors[idx] + jitter[idx];
      for (int it = 0; it < 16; ++it) p -= scene.bone_distance(p) * scene.bone_normal(p, 0.2 * g);
      V3 c = p + (r + 0.5 * g) * scene.bone_normal(p, 0.2 * g);
      // Centre it on a voxel so the centre voxel is wholly inside the sphere at every size.
      for (int a = 0; a < 3; ++a) c[a] = o + h * std::clamp(std::round((c[a] - o) / h), 0.0, double(n - 1));
      const double dc = scene.bone_distance(c);
      if (!(dc > -r && dc < r + 2.0 * h + 2.0 * g)) continue;
      if (scene.body_distance(c) > -3.0 * r) continue;
      bool clear = true;
      for (const V3& f : scene.fiducials) clear = clear && len(f - c) >= 20.0 * g;
      if (scene.screw)
        clear = clear && segment_distance(c, scene.screw->head, scene.screw->head + scene.screw->length *
                                                                                       scene.screw->dir) >=
                             r + scene.screw->head_radius + 3.0 * g;
      if (clear) scene.fiducials.push_back(c);
    }
    scene.fiducial_r = r;
    ph.fiducials = scene.fiducials;
    ph.fiducial_radius_mm = r;
  }

  // The voxels: each from its own position only, so the slice partition cannot change them.
  ph.hu.voxels.assign(geo.voxel_count(), float(kAirHU));
  const double q = 0.25 * h;
  tbb::parallel_for(tbb::blocked_range<int>(0, n), [&](const tbb::blocked_range<int>& range) {
    for (int k = range.begin(); k != range.end(); ++k)
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          const V3 p(o + h * i, o + h * j, o + h * k);
          double near = 0;
          double v = scene.value(p, &near);
          if (near < band) {
            double sum = 0;
            for (int s = 0; s < 8; ++s)
              sum += scene.value(p + V3((s & 1) ? q : -q, (s & 2) ? q : -q, (s & 4) ? q : -q), nullptr);
            v = sum * 0.125;
          }
          ph.hu.voxels[geo.linear_index(i, j, k)] = float(v);
        }
  });
  return ph;
}

}  // namespace fluoro
