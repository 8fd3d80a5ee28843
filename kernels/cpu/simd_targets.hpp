#pragma once
// The SIMD instruction sets the cpu backend's kernels were compiled for and this CPU runs (Highway
// dispatches each call to the best of them), and a cap on them, `fluoro --simd NAME`: to compare
// instruction sets on one machine, or to reproduce on an AVX-512 machine what a CPU without it runs.
// Results may differ in the last bits between sets (lane counts change summation order), within
// the kernels' tolerances (tests/kernel_guard_test.cpp runs every set).
#include <string>
#include <string_view>
#include <vector>

namespace fluoro::cpu {

// Highway's names of the sets both compiled and supported here (whatever the cap), best first, for example
// AVX3 (AVX-512), AVX2, SSE4, SSSE3, and SCALAR or EMU128 (portable C++).
std::vector<std::string> simd_targets();

// The set the kernels run now: the best one not capped.
std::string simd_target();

// Caps the kernels at `name` (one of simd_targets(), any case). Call it before the first kernel
// runs. Throws InputError naming the choices otherwise. The cap holds until something calls
// hwy::SupportedTargets() again: Highway 1.0 then re-chooses from every set the CPU has (nothing in
// the program does; simd_target() asks the dispatch itself, so it would tell).
void limit_simd(std::string_view name);

}  // namespace fluoro::cpu
