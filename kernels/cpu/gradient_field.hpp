#pragma once
// The cpu backend's Op::gradient_field: separable Gaussian-derivative filtering in float fused
// with the optional resampling to an isotropic grid (each axis filtered and interpolated in one
// pass), one output slice at a time over oneTBB.
#include <memory>

#include "engine/ops.hpp"
#include "kernels/cpu/cpu_volume.hpp"

namespace fluoro::cpu {

std::shared_ptr<CpuVolume> compute_gradient_field(const CpuVolume& mu, const GradientFieldParams& params,
                                                  const void* owner);

}  // namespace fluoro::cpu
