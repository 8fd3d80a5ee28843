#pragma once
// The cpu backend: every op on oneTBB threads with Highway SIMD (kernels/cpu/). Named "cpu" in
// the registry (kernels/backend_registry.hpp).
#include <memory>

#include "engine/backend.hpp"

namespace fluoro::cpu {

std::unique_ptr<Backend> make_cpu_backend();

}  // namespace fluoro::cpu
