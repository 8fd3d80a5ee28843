// Highway dynamic dispatch: this file is compiled once per SIMD target and the best one for the
// running CPU is picked at the first call.
#include <algorithm>
#include <cmath>

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "kernels/cpu/ray_march.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "kernels/cpu/ray_march.hpp"

HWY_BEFORE_NAMESPACE();
namespace fluoro::cpu::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using DF = hn::ScalableTag<float>;
using DI = hn::RebindToSigned<DF>;
using VF = hn::Vec<DF>;
using VI = hn::Vec<DI>;

// Trilinear reads at up to Lanes positions: the voxel index of the lower corner and the weights.
struct Corner {
  VI base, brick;
  VI ix, iy, iz;  // the lower corner (its brick's faces bound the leap out of an empty brick)
  VF fx, fy, fz;
};

HWY_INLINE Corner locate(const PaddedGrid& g, VF x, VF y, VF z) {
  const DF df;
  const DI di;
  // Clamping keeps lanes of finished rays (and rounding at the box faces) inside the padding.
  x = hn::Min(hn::Max(x, hn::Zero(df)), hn::Set(df, float(g.nx) - 1.001f));
  y = hn::Min(hn::Max(y, hn::Zero(df)), hn::Set(df, float(g.ny) - 1.001f));
  z = hn::Min(hn::Max(z, hn::Zero(df)), hn::Set(df, float(g.nz) - 1.001f));
  // The float clamp alone is not enough: n - 1.001 rounds to n - 1 once n reaches 2^15. The
  // integer clamp keeps every read (lower corner + 1 along each axis) inside the padded array.
  const VI ix = hn::Min(hn::ConvertTo(di, x), hn::Set(di, g.nx - 2));
  const VI iy = hn::Min(hn::ConvertTo(di, y), hn::Set(di, g.ny - 2));
  const VI iz = hn::Min(hn::ConvertTo(di, z), hn::Set(di, g.nz - 2));
  Corner c;
  c.ix = ix;
  c.iy = iy;
  c.iz = iz;
  c.fx = hn::Sub(x, hn::ConvertTo(df, ix));
  c.fy = hn::Sub(y, hn::ConvertTo(df, iy));
  c.fz = hn::Sub(z, hn::ConvertTo(df, iz));
  c.base = hn::Add(hn::Mul(hn::Add(hn::Mul(iz, hn::Set(di, g.ny)), iy), hn::Set(di, g.nx)), ix);
  if (g.occupancy) {
    const VI bx = hn::ShiftRightSame(ix, g.brick_shift), by = hn::ShiftRightSame(iy, g.brick_shift),
             bz = hn::ShiftRightSame(iz, g.brick_shift);
    c.brick = hn::Add(hn::Mul(hn::Add(hn::Mul(bz, hn::Set(di, g.bricks_y)), by), hn::Set(di, g.bricks_x)), bx);
  }
  return c;
}

HWY_INLINE VF lerp(VF a, VF b, VF f) { return hn::MulAdd(hn::Sub(b, a), f, a); }

// The two 16-bit halves of 32-bit lanes as floats (unscaled).
template <bool kSigned>
HWY_INLINE void unpack(VI w, VF& lo, VF& hi) {
  const DF df;
  if constexpr (kSigned) {
    lo = hn::ConvertTo(df, hn::ShiftRight<16>(hn::ShiftLeft<16>(w)));  // arithmetic shifts
    hi = hn::ConvertTo(df, hn::ShiftRight<16>(w));
  } else {
    const hn::RebindToUnsigned<DF> du;
    lo = hn::ConvertTo(df, hn::And(w, hn::Set(DI(), 0xFFFF)));
    hi = hn::ConvertTo(df, hn::BitCast(DI(), hn::ShiftRight<16>(hn::BitCast(du, w))));
  }
}

// The word indices of one sample at the lower corner's z and at z + 1, as plain integers: the
// words are read by scalar loads, which measured faster than vector gathers (see below).
struct QuadIndex {
  HWY_ALIGN int32_t at[2][hn::MaxLanes(DI())];
};

HWY_INLINE void quad_index(const Corner& c, VI dz, QuadIndex& q) {
  const DI di;
  hn::Store(c.base, di, q.at[0]);
  hn::Store(hn::Add(c.base, dz), di, q.at[1]);
}

// The words of every lane at z level `level`, split into the voxel pairs (x, x + 1) of row y and
// of row y + 1, one pair per 32-bit lane in ray order. Scalar loads assembled through the stack:
// on the AMD Zen 5 machine of docs/benchmarks.md the GPR score benchmark took 367 ms against 530
// with hardware gathers of 32-bit x-neighbour pairs (the previous layout), and hardware gathers of
// these 64-bit words were slower than those of pairs.
HWY_INLINE void load_rows(const uint64_t* HWY_RESTRICT data, const QuadIndex& q, int level, VI& row0, VI& row1) {
  const DI di;
  const size_t lanes = hn::Lanes(di);
#if HWY_TARGET == HWY_SCALAR
  const uint64_t w = data[q.at[level][0]];
  row0 = hn::Set(di, int32_t(uint32_t(w)));
  row1 = hn::Set(di, int32_t(uint32_t(w >> 32)));
  (void)lanes;
#else
  HWY_ALIGN uint64_t words[hn::MaxLanes(di)];
  for (size_t l = 0; l < lanes; ++l) words[l] = data[q.at[level][l]];
  // Little-endian: even 32-bit lanes are the words' low halves (row y), odd ones row y + 1.
  const VI a = hn::Load(di, reinterpret_cast<const int32_t*>(words));
  const VI b = hn::Load(di, reinterpret_cast<const int32_t*>(words + lanes / 2));
  row0 = hn::ConcatEven(di, b, a);
  row1 = hn::ConcatOdd(di, b, a);
#endif
}

// Vector voxels: the three components of every lane's voxel at word index q.at[level] + offset,
// unscaled. The words are split into their low halves (x | y << 16) and high ones (z | unused).
template <bool kSigned>
HWY_INLINE void load_vector(const uint64_t* HWY_RESTRICT data, const QuadIndex& q, int level, int offset, VF& x,
                            VF& y, VF& z) {
  const DI di;
  const size_t lanes = hn::Lanes(di);
  VI xy, zw;
#if HWY_TARGET == HWY_SCALAR
  const uint64_t w = data[q.at[level][0] + offset];
  xy = hn::Set(di, int32_t(uint32_t(w)));
  zw = hn::Set(di, int32_t(uint32_t(w >> 32)));
  (void)lanes;
#else
  HWY_ALIGN uint64_t words[hn::MaxLanes(di)];
  for (size_t l = 0; l < lanes; ++l) words[l] = data[q.at[level][l] + offset];
  const VI a = hn::Load(di, reinterpret_cast<const int32_t*>(words));
  const VI b = hn::Load(di, reinterpret_cast<const int32_t*>(words + lanes / 2));
  xy = hn::ConcatEven(di, b, a);
  zw = hn::ConcatOdd(di, b, a);
#endif
  unpack<kSigned>(xy, x, y);
  VF unused;
  unpack<kSigned>(zw, z, unused);
}

#if HWY_TARGET != HWY_SCALAR
// The 16 bytes at words + at[0], words + at[1], ... side by side in one vector of 64-bit lanes
// (Lanes(d) / 2 of them), assembled in registers.
template <class D64>
HWY_INLINE hn::Vec<D64> load_chunks(D64 d, const int64_t* HWY_RESTRICT words, const int32_t* at) {
  if constexpr (hn::MaxLanes(d) <= 2) {
    return hn::LoadU(d, words + at[0]);
  } else {
    const hn::Half<D64> dh;
    return hn::Combine(d, load_chunks(dh, words, at + hn::MaxLanes(dh) / 2), load_chunks(dh, words, at));
  }
}
#endif

// Vector voxels x and x + 1 of every lane's row: the two neighbours' words are adjacent, so each
// lane reads them with one 16-byte load, assembled in registers (two load_vector calls: two 8-byte
// loads per lane, through the stack). The same values; 5 % off the GPR score benchmark, and 1.55x
// slower when these 16 bytes went through the stack (docs/benchmarks.md, "Direct sums").
template <bool kSigned>
HWY_INLINE void load_vector_pair(const uint64_t* HWY_RESTRICT data, const QuadIndex& q, int level, int offset,
                                 VF (&a)[3], VF (&b)[3]) {
#if HWY_TARGET == HWY_SCALAR
  load_vector<kSigned>(data, q, level, offset, a[0], a[1], a[2]);
  load_vector<kSigned>(data, q, level, offset + 1, b[0], b[1], b[2]);
#else
  const DI di;
  const hn::Repartition<int64_t, DI> d64;
  const size_t half = hn::Lanes(d64);  // Lanes(di) / 2
  const int32_t* at = q.at[level];
  const int64_t* w = reinterpret_cast<const int64_t*>(data) + offset;
  // chunks(i): the 16 bytes of lanes i, i + 1, ... (half / 2 of them) side by side, in registers.
  const auto chunks = [&](size_t i) { return load_chunks(d64, w, at + i); };
  const auto c0 = chunks(0), c1 = chunks(half / 2), c2 = chunks(half), c3 = chunks(3 * half / 2);
  // The words of voxel x (even) and x + 1 (odd) of the first and of the second half of the lanes,
  // as load_vector assembles them from single words.
  const VI voxels[2][2] = {{hn::BitCast(di, hn::ConcatEven(d64, c1, c0)), hn::BitCast(di, hn::ConcatEven(d64, c3, c2))},
                           {hn::BitCast(di, hn::ConcatOdd(d64, c1, c0)), hn::BitCast(di, hn::ConcatOdd(d64, c3, c2))}};
  VF* out[2] = {a, b};
  for (int v = 0; v < 2; ++v) {
    const VI xy = hn::ConcatEven(di, voxels[v][1], voxels[v][0]), zw = hn::ConcatOdd(di, voxels[v][1], voxels[v][0]);
    unpack<kSigned>(xy, out[v][0], out[v][1]);
    VF unused;
    unpack<kSigned>(zw, out[v][2], unused);
  }
#endif
}

// Trilinear of vector voxels, in units of each component's quantum: eight voxels per lane, the
// same arithmetic in the same order as the scalar trilinear below.
template <bool kSigned>
HWY_INLINE void trilinear_vector(const uint64_t* HWY_RESTRICT data, const QuadIndex& q, const Corner& c, int nx,
                                 VF& gx, VF& gy, VF& gz) {
  VF row[2][2][3];  // [z level][y row][component], already interpolated along x
  for (int level = 0; level < 2; ++level)
    for (int r = 0; r < 2; ++r) {
      VF a[3], b[3];
      load_vector_pair<kSigned>(data, q, level, r * nx, a, b);
      for (int k = 0; k < 3; ++k) row[level][r][k] = lerp(a[k], b[k], c.fx);
    }
  VF out[3];
  for (int k = 0; k < 3; ++k)
    out[k] = lerp(lerp(row[0][0][k], row[0][1][k], c.fy), lerp(row[1][0][k], row[1][1][k], c.fy), c.fz);
  gx = out[0];
  gy = out[1];
  gz = out[2];
}

// Trilinear in units of the grid's quantum (multiply by its scale): two loads of 8-byte words per
// lane, the same arithmetic in the same order as interpolating single voxels.
template <bool kSigned>
HWY_INLINE VF trilinear(const uint64_t* HWY_RESTRICT data, const QuadIndex& q, const Corner& c) {
  VI row0, row1;
  VF a, b;
  load_rows(data, q, 0, row0, row1);
  unpack<kSigned>(row0, a, b);
  const VF x00 = lerp(a, b, c.fx);
  unpack<kSigned>(row1, a, b);
  const VF x10 = lerp(a, b, c.fx);
  load_rows(data, q, 1, row0, row1);
  unpack<kSigned>(row0, a, b);
  const VF x01 = lerp(a, b, c.fx);
  unpack<kSigned>(row1, a, b);
  const VF x11 = lerp(a, b, c.fx);
  return lerp(lerp(x00, x10, c.fy), lerp(x01, x11, c.fy), c.fz);
}

// Steps along one axis, from the position e + s * kk, until the ray comes within `margin` voxels
// of the face of the brick of the lower corner index i (bricks of 1 << shift voxels) it moves
// towards: the upper face when moving up, the lower one when moving down; unbounded when not moving
// along the axis. The margin covers the rounding of positions (a few ulps of the largest
// coordinate: just under a power-of-two face, floats are twice as dense as just above it).
HWY_INLINE VF steps_to_face(VI i, VF s, VF kk, VF e, int shift, VF margin) {
  const DF df;
  const VF lower = hn::ConvertTo(df, hn::ShiftLeftSame(hn::ShiftRightSame(i, shift), shift));
  const VF p = hn::MulAdd(s, kk, e);
  const auto up = hn::Gt(s, hn::Zero(df));
  const VF room = hn::Sub(hn::IfThenElse(up, hn::Sub(hn::Add(lower, hn::Set(df, float(1 << shift))), p), hn::Sub(p, lower)),
                          margin);
  const VF speed = hn::Abs(s);
  const auto moving = hn::Gt(speed, hn::Set(df, 1e-12f));
  return hn::IfThenElse(moving, hn::Div(room, hn::IfThenElse(moving, speed, hn::Set(df, 1.0f))), hn::Set(df, 1e9f));
}

// The steps [begin, end) of a group of rays at which some ray with samples is inside the occupied
// box (PaddedGrid::occupied_lo, _hi), by a slab test per lane in units of its step, widened by two
// steps each way against rounding: every sample outside is zero, so a group marches only these.
// False when no ray of the group enters the box (nothing to march). Positions are e + s * (k + 0.5).
HWY_INLINE bool occupied_steps(const PaddedGrid& g, VF ex, VF ey, VF ez, VF sx, VF sy, VF sz, VI n, int max_n,
                               int& begin, int& end) {
  const DF df;
  const DI di;
  const VF far = hn::Set(df, 1e9f);
  VF t_in = hn::Neg(far), t_out = far;  // the position parameter k + 0.5 where a lane is inside
  const VF e[3] = {ex, ey, ez}, s[3] = {sx, sy, sz};
  for (int a = 0; a < 3; ++a) {
    const VF lo = hn::Set(df, g.occupied_lo[a]), hi = hn::Set(df, g.occupied_hi[a]);
    const auto moving = hn::Gt(hn::Abs(s[a]), hn::Set(df, 1e-6f));
    const VF inv = hn::Div(hn::Set(df, 1.0f), hn::IfThenElse(moving, s[a], hn::Set(df, 1.0f)));
    const VF ta = hn::Mul(hn::Sub(lo, e[a]), inv), tb = hn::Mul(hn::Sub(hi, e[a]), inv);
    // Not moving along this axis (within a thousandth of a voxel over any ray): inside the slab at
    // every step or at none, judged with a voxel to spare.
    const auto inside = hn::And(hn::Ge(e[a], hn::Sub(lo, hn::Set(df, 1.0f))), hn::Le(e[a], hn::Add(hi, hn::Set(df, 1.0f))));
    t_in = hn::Max(t_in, hn::IfThenElse(moving, hn::Min(ta, tb), hn::IfThenElse(inside, hn::Neg(far), far)));
    t_out = hn::Min(t_out, hn::IfThenElse(moving, hn::Max(ta, tb), hn::IfThenElse(inside, far, hn::Neg(far))));
  }
  const auto enters = hn::And(hn::RebindMask(df, hn::Gt(n, hn::Zero(di))), hn::Le(t_in, t_out));
  if (hn::AllFalse(df, enters)) return false;
  const float first = hn::GetLane(hn::MinOfLanes(df, hn::IfThenElse(enters, t_in, far)));
  const float last = hn::GetLane(hn::MaxOfLanes(df, hn::IfThenElse(enters, t_out, hn::Neg(far))));
  const float steps = float(max_n);
  begin = int(std::floor(std::clamp(first, -2.0f, steps))) - 2;
  begin = std::max(begin, 0);
  end = int(std::ceil(std::clamp(last, -2.0f, steps))) + 2;
  end = std::min(end, max_n);
  return true;
}

// Runs body(kk, corner, live) for the sample steps k of the lanes starting at ray r, where kk
// is k + 0.5 and live masks the lanes whose sample can be non-zero (active, in an occupied
// brick). Steps where no lane is live are skipped; when every active lane is in an empty brick,
// the group leaps as far as the nearest occupied brick allows (the occupancy map holds Chebyshev
// distances in bricks) or out of the brick each lane is in, whichever is further, which is exact:
// the skipped samples are all zero. Before and after the steps at which some lane is inside the
// occupied bricks' box (occupied_steps), nothing is marched at all: a ray through a bone's
// surroundings otherwise leaps its way in from the volume's face and out again (about half the
// iterations of the femur phantom's bone DRRs), each leap a gather and a reduction in sequence.
// kRound: locate the nearest voxel (positions shifted by half a voxel before truncation).
template <bool kRound = false, class Body>
HWY_INLINE void march_lanes(const PaddedGrid& g, const RayPacket& rays, int r, Body&& body) {
  const DF df;
  const DI di;
  const VI n = hn::LoadU(di, rays.n + r);
  const int max_n = hn::GetLane(hn::MaxOfLanes(di, n));
  const VF half = hn::Set(df, kRound ? 0.5f : 0.0f);
  const VF ex = hn::Add(hn::LoadU(df, rays.entry_x + r), half), ey = hn::Add(hn::LoadU(df, rays.entry_y + r), half),
           ez = hn::Add(hn::LoadU(df, rays.entry_z + r), half);
  const VF sx = hn::LoadU(df, rays.step_x + r), sy = hn::LoadU(df, rays.step_y + r),
           sz = hn::LoadU(df, rays.step_z + r);
  // Steps per voxel of travel along the fastest axis (1 / max |step|), for the leap length.
  const VF steps_per_voxel =
      hn::Div(hn::Set(df, 1.0f), hn::Max(hn::Set(df, 1e-6f), hn::Max(hn::Abs(sx), hn::Max(hn::Abs(sy), hn::Abs(sz)))));
  // After a step with data, the next few are read without consulting the occupancy map: in dense
  // regions the map's gather and test sit on the critical path of every step, and reading a
  // sample that happens to be zero is always correct.
  constexpr int kDenseRun = 3;
  // 8 ulps of the largest padded coordinate, in voxels (steps_to_face).
  const VF face_margin = hn::Set(df, float(std::max(g.nx, std::max(g.ny, g.nz))) * 0x1p-20f);
  int unchecked = 0;
  int k_begin = 0, k_end = max_n;
  if (g.occupancy && !occupied_steps(g, ex, ey, ez, sx, sy, sz, n, max_n, k_begin, k_end)) return;
  for (int k = k_begin; k < k_end;) {
    const VF kk = hn::Set(df, float(k) + 0.5f);
    const auto active = hn::RebindMask(df, hn::Lt(hn::Set(di, k), n));
    const Corner c = locate(g, hn::MulAdd(sx, kk, ex), hn::MulAdd(sy, kk, ey), hn::MulAdd(sz, kk, ez));
    if (!g.occupancy || unchecked > 0) {
      body(kk, c, active);
      --unchecked;
      ++k;
      continue;
    }
    const VI distance = hn::GatherIndex(di, g.occupancy, c.brick);
    const auto live = hn::And(active, hn::RebindMask(df, hn::Eq(distance, hn::Zero(di))));
    if (!hn::AllFalse(df, live)) {
      body(kk, c, live);
      unchecked = kDenseRun;
      ++k;
      continue;
    }
    // All active lanes are in empty bricks: a brick at distance d leaves brick * (d - 1)
    // voxels of guaranteed empty space around it along every axis ...
    const VF room = hn::Mul(hn::ConvertTo(df, hn::Sub(distance, hn::Set(di, 1))), hn::Set(df, float(1 << g.brick_shift)));
    // ... and each lane's lower corner stays in its own empty brick until the ray crosses one of
    // the brick's faces, t steps on (the least over the axes, `face_margin` voxels short of it):
    // the first sample outside is floor(t) + 1 steps on (ceil(t) moving up, where a sample exactly
    // on the upper face is outside: hence 1e-3 of a step more), and the ones before it read only
    // zeros. So a ray next to bone (d = 1) leaps too.
    const VF exit_steps = hn::Min(steps_to_face(c.ix, sx, kk, ex, g.brick_shift, face_margin),
                                  hn::Min(steps_to_face(c.iy, sy, kk, ey, g.brick_shift, face_margin),
                                          steps_to_face(c.iz, sz, kk, ez, g.brick_shift, face_margin)));
    const VF exit_leap = hn::Add(hn::Floor(hn::Sub(exit_steps, hn::Set(df, 1e-3f))), hn::Set(df, 1.0f));
    // At most the longest ray's steps (an almost zero step would overflow the int).
    const VF lane_leap = hn::Min(hn::IfThenElse(active, hn::Max(hn::Floor(hn::Mul(room, steps_per_voxel)), exit_leap),
                                                hn::Set(df, 1e9f)),
                                 hn::Set(df, float(max_n)));
    const int leap = int(hn::GetLane(hn::MinOfLanes(df, lane_leap)));
    k += leap > 1 ? leap : 1;
  }
}

template <bool kSigned>
void march_line_integrals_impl(const PaddedGrid& g, const RayPacket& rays, int count, float* out) {
  const DF df;
  const DI di;
  const size_t lanes = hn::Lanes(df);
  const VI dz = hn::Set(di, g.nx * g.ny);
  const VF scale = hn::Set(df, g.scale[0]);
  for (int r = 0; r < count; r += int(lanes)) {
    VF acc = hn::Zero(df);
    march_lanes(g, rays, r, [&](VF, const Corner& c, auto live) {
      QuadIndex q;
      quad_index(c, dz, q);
      acc = hn::Add(acc, hn::IfThenElseZero(live, trilinear<kSigned>(g.words, q, c)));
    });
    const auto valid = hn::FirstN(df, size_t(count - r));
    hn::BlendedStore(hn::Mul(hn::Mul(acc, scale), hn::LoadU(df, rays.h + r)), valid, df, out + r);
  }
}

template <bool kSigned, bool kNearest>
void march_weighted_gradients_impl(const PaddedGrid& g, const RayPacket& rays, int count, float* out_x,
                                   float* out_y, float* out_z) {
  const DF df;
  const DI di;
  const size_t lanes = hn::Lanes(df);
  const VI dz = hn::Set(di, g.nx * g.ny);
  for (int r = 0; r < count; r += int(lanes)) {
    const VF t0 = hn::LoadU(df, rays.t0 + r), h = hn::LoadU(df, rays.h + r);
    VF ax = hn::Zero(df), ay = hn::Zero(df), az = hn::Zero(df);
    march_lanes<kNearest>(g, rays, r, [&](VF kk, const Corner& c, auto live) {
      const VF w = hn::IfThenElseZero(live, hn::MulAdd(kk, h, t0));
      QuadIndex q;
      quad_index(c, dz, q);
      VF gx, gy, gz;
      if constexpr (kNearest) load_vector<kSigned>(g.words, q, 0, 0, gx, gy, gz);  // the corner itself
      else trilinear_vector<kSigned>(g.words, q, c, g.nx, gx, gy, gz);
      ax = hn::MulAdd(w, gx, ax);
      ay = hn::MulAdd(w, gy, ay);
      az = hn::MulAdd(w, gz, az);
    });
    const auto valid = hn::FirstN(df, size_t(count - r));
    hn::BlendedStore(hn::Mul(ax, hn::Mul(h, hn::Set(df, g.scale[0]))), valid, df, out_x + r);
    hn::BlendedStore(hn::Mul(ay, hn::Mul(h, hn::Set(df, g.scale[1]))), valid, df, out_y + r);
    hn::BlendedStore(hn::Mul(az, hn::Mul(h, hn::Set(df, g.scale[2]))), valid, df, out_z + r);
  }
}

void MarchLineIntegrals(const PaddedGrid& g, const RayPacket& rays, int count, float* out) {
  if (g.is_signed) march_line_integrals_impl<true>(g, rays, count, out);
  else march_line_integrals_impl<false>(g, rays, count, out);
}

void MarchWeightedGradients(const PaddedGrid& g, const RayPacket& rays, int count, bool nearest,
                            float* out_x, float* out_y, float* out_z) {
  if (nearest) {
    if (g.is_signed) march_weighted_gradients_impl<true, true>(g, rays, count, out_x, out_y, out_z);
    else march_weighted_gradients_impl<false, true>(g, rays, count, out_x, out_y, out_z);
  } else {
    if (g.is_signed) march_weighted_gradients_impl<true, false>(g, rays, count, out_x, out_y, out_z);
    else march_weighted_gradients_impl<false, false>(g, rays, count, out_x, out_y, out_z);
  }
}

const char* MarchTarget() { return hwy::TargetName(HWY_TARGET); }

}  // namespace fluoro::cpu::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace fluoro::cpu {
HWY_EXPORT(MarchLineIntegrals);
HWY_EXPORT(MarchWeightedGradients);
HWY_EXPORT(MarchTarget);

int brick_shift_for(double smallest_spacing_mm) {
  // Measured (docs/benchmarks.md, "Brick size"): whole registrations of five CTs with bricks of
  // 2, 4 and 8 voxels. 4 was fastest on every CT of 2 mm voxels or finer; on the 3 mm pelvis CT,
  // whose 12 mm bricks hold mostly empty space around its thin bone, 2 was.
  return smallest_spacing_mm >= 2.5 ? 1 : 2;
}

void march_line_integrals(const PaddedGrid& grid, const RayPacket& rays, int count, float* out) {
  HWY_DYNAMIC_DISPATCH(MarchLineIntegrals)(grid, rays, count, out);
}

void march_weighted_gradients(const PaddedGrid& grid, const RayPacket& rays, int count, bool nearest,
                              float* out_x, float* out_y, float* out_z) {
  HWY_DYNAMIC_DISPATCH(MarchWeightedGradients)(grid, rays, count, nearest, out_x, out_y, out_z);
}

const char* march_target() { return HWY_DYNAMIC_DISPATCH(MarchTarget)(); }
}  // namespace fluoro::cpu
#endif
