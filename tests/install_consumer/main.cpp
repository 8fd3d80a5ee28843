// Uses the installed library as a user would: the backends by name (from the installed static
// library's registry), a phantom, a DRR on two backends, the version. Exit 0 when the cpu
// and reference DRRs agree and see the bone.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "datasets/c_arm.hpp"
#include "datasets/phantom.hpp"
#include "engine/attenuation.hpp"
#include "engine/backend.hpp"
#include "engine/version.hpp"
#include "kernels/backend_registry.hpp"
#include "pipelines/registration/error_metrics.hpp"

int main() {
  using namespace fluoro;
  std::string names;
  for (const auto& n : backend_names()) names += n + " ";
  std::printf("fluoro %s, backends: %s\n", kVersion, names.c_str());
  if (std::strcmp(kVersion, EXPECTED_VERSION) != 0) return 1;
  PhantomParams pp;
  pp.size = 32;
  const Phantom phantom = make_phantom(pp);
  CArmGeometry g;
  g.pixels = 32;
  g.pixel_mm = 9.6;
  const PinholeCamera camera = c_arm_view(g, 0);
  const Pose pose = Pose::Identity();
  float peak[2] = {0, 0};
  double largest_difference = 0;
  std::vector<Image> drrs;
  for (const char* name : {"cpu", "reference"}) {
    auto backend = make_backend(name);
    const auto mu = backend->upload(hu_to_attenuation(phantom.hu));
    drrs.push_back(backend->drr(*mu, std::span(&pose, 1), std::span(&camera, 1), {1.0, {}})[0]);
  }
  for (int i = 0; i < 2; ++i) peak[i] = *std::max_element(drrs[i].pixels.begin(), drrs[i].pixels.end());
  for (size_t p = 0; p < drrs[0].pixels.size(); ++p)
    largest_difference = std::max(largest_difference, double(std::abs(drrs[0].pixels[p] - drrs[1].pixels[p])));
  const auto surface = surface_points(phantom.hu, 250, 100);
  std::printf("DRR peak %.3f (cpu) %.3f (reference), largest difference %.4f; %zu surface points\n", peak[0], peak[1],
              largest_difference, surface.size());
  return peak[0] > 1.0 && largest_difference < 0.01 * peak[1] && !surface.empty() ? 0 : 1;
}
