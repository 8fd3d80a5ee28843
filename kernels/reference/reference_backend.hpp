#pragma once
// The reference backend: every op in plain double-precision loops, the oracle the other backends
// are tested against (tests/backend_equivalence_test.cpp). Named "reference" in the registry.
#include <memory>

#include "engine/backend.hpp"

namespace fluoro {

std::unique_ptr<Backend> make_reference_backend();

}  // namespace fluoro
