#pragma once
// The ops every backend implements, and their parameters. One definition for all backends: the
// reference backend is the oracle, the others must agree with it within each op's tolerance
// (tests/backend_equivalence_test.cpp).
#include <Eigen/Core>
#include <string_view>
#include <vector>

namespace fluoro {

enum class Op {
  gradient_field,       // Gaussian-derivative gradient of an attenuation volume
  drr,                  // line integral per pixel
  gradient_projection,  // expected 2D image gradient at given pixels (seed ch. 2, eq. 1-3)
  gpr_score,            // sum of direction-consistent gradient projection magnitudes (eq. 4)
  gradient_floor,       // a gradient field with its weak voxels zeroed (empty space for the marchers)
};
constexpr Op kAllOps[] = {Op::gradient_field, Op::drr, Op::gradient_projection, Op::gpr_score, Op::gradient_floor};
std::string_view op_name(Op op);

struct GradientFieldParams {
  double sigma_mm = 1.0;  // Gaussian scale of the derivative filter
  // > 0: resample the gradient to a grid of this spacing (the seed used 0.5 mm; isotropic unless
  // keep_coarser_axes) over the same extent, with the volume's direction. 0 keeps the volume's grid.
  double resample_spacing_mm = 0.0;
  // With resample_spacing_mm > 0: an axis whose voxels are already coarser than it keeps its own
  // spacing instead of being upsampled (a registration's fields: a CT of 1.5 mm slices gives 1.5 mm
  // along z, not 1 mm of interpolated slices that hold nothing more and take 50 % more memory).
  bool keep_coarser_axes = false;
};

// Op::gradient_floor: every voxel whose gradient magnitude is below relative_tolerance times the
// field's largest voxel magnitude becomes zero. Interior bone texture is weak next to the cortical
// edges the GPR score is made of; zeroing it makes empty space that the marchers skip. The price
// is bounded: a trilinear sample of the floored field differs from the original's by less than the
// absolute floor f = relative_tolerance * max |g| (a convex combination of voxel differences each
// below f), so a pixel's expected gradient moves by less than f * h * sum_k t_k * ||(axis_u,
// axis_v)|| / |K^-1 p| (engine/ray_setup.hpp's terms; tests/gradient_floor_test.cpp checks it).
struct GradientFloorParams {
  double relative_tolerance = 0.0;  // in [0, 1)
};

// A rectangle of pixels; width or height 0 means the whole image.
struct PixelWindow {
  int x0 = 0, y0 = 0, width = 0, height = 0;
};

struct DrrParams {
  double step_mm = 1.0;  // largest sample spacing along a ray (the actual one divides the chord)
  PixelWindow window;
};

// How rays read a gradient field. Nearest is the seed's fast path: a field resampled to a fine
// grid (GradientFieldParams::resample_spacing_mm, the seed used 0.5 mm) read at the nearest voxel,
// one read per component instead of eight.
enum class Sampling { trilinear, nearest };

struct ProjectionParams {
  double step_mm = 1.0;
  Sampling sampling = Sampling::trilinear;
};

// The edge pixels of one X-ray and, for each, the direction the expected gradient (the derivative
// of the DRR, which grows with attenuation) should point in: for a log-domain X-ray (bone dark)
// that is minus the X-ray's own gradient direction. Directions are unit vectors.
struct EdgePixels {
  std::vector<Eigen::Vector2f> pixels;
  std::vector<Eigen::Vector2f> directions;
};

struct GprParams {
  ProjectionParams projection;
  // A pixel whose expected gradient deviates from its direction by more than this angle counts
  // zero (the seed's outlier rejection of foreign objects and other anatomy).
  double max_angle_deg = 30.0;
};

}  // namespace fluoro
