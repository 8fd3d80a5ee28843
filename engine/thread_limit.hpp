#pragma once
// One limit on the threads every pool of the program may use (`fluoro --threads N`): oneTBB's
// (the engine's parallel loops, and Embree and OpenCV, which Debian builds on oneTBB), OpenCV's
// own setting, ITK's multithreader (volume reading), and lavapipe's (the Vulkan CPU driver, which
// rasterises and dispatches on threads of its own).
namespace fluoro {

// Applies the limit for the rest of the process. Call it before the first parallel work and before
// any Vulkan device is opened (lavapipe reads its thread count when it is loaded). n >= 1.
void limit_threads(int n);

// The most threads oneTBB lets one parallel loop use now (the limit if set, else the cores).
int thread_limit();

}  // namespace fluoro
