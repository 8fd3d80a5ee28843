#include "datasets/xray_physics.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include <opencv2/imgproc.hpp>

#include "engine/error.hpp"

namespace fluoro {
namespace {

// A Gaussian blur of a float image in place; the reflected border keeps a flat field flat (the
// scatter and the detector see no edge where the image ends).
void gaussian_blur(std::vector<float>& pixels, int width, int height, double sigma) {
  cv::Mat m(height, width, CV_32F, pixels.data());
  cv::GaussianBlur(m, m, cv::Size(0, 0), sigma, sigma, cv::BORDER_REFLECT);
}

}  // namespace

double largest_beam_hardening(const XrayPhysics& p) { return 1.0 / (2.0 * p.max_line_integral); }

std::optional<XrayPhysicsProblem> xray_physics_problem(const XrayPhysics& p) {
  const std::pair<const char*, double> values[] = {{"beam_hardening", p.beam_hardening}, {"scatter", p.scatter_to_primary},
                                                   {"scatter_sigma_px", p.scatter_sigma_px}, {"blur_px", p.blur_px},
                                                   {"photons", p.photons}};
  for (const auto& [key, v] : values)
    if (!std::isfinite(v) || v < 0) return XrayPhysicsProblem{key, "must be a number >= 0"};
  if (!std::isfinite(p.max_line_integral) || !(p.max_line_integral > 0))
    return XrayPhysicsProblem{"max_line_integral", "must be positive"};
  if (p.beam_hardening > largest_beam_hardening(p)) {
    char text[160];
    std::snprintf(text, sizeof text, "must be at most %.4g (1 / (2 x max_line_integral)): beyond it L - b L^2 turns down",
                  largest_beam_hardening(p));
    return XrayPhysicsProblem{"beam_hardening", text};
  }
  if (p.blur_px > 100) return XrayPhysicsProblem{"blur_px", "must be at most 100 pixels"};
  if (p.scatter_sigma_px > 10000) return XrayPhysicsProblem{"scatter_sigma_px", "must be at most 10000 pixels"};
  if (p.photons > 0 && p.photons < 1) return XrayPhysicsProblem{"photons", "must be 0 (no noise) or at least 1"};
  // Poisson draws of a mean near 2^63 never return (libstdc++ rejects every draw); at 1e12 photons
  // the noise is already a millionth of the signal.
  if (p.photons > 1e12) return XrayPhysicsProblem{"photons", "must be at most 1e12"};
  if (p.scatter_to_primary > 100) return XrayPhysicsProblem{"scatter", "must be at most 100 (scatter-to-primary ratio)"};
  return std::nullopt;
}

Image simulate_xray_physics(const Image& drr, const XrayPhysics& p) {
  if (const auto bad = xray_physics_problem(p)) throw_input_error("x-ray physics", bad->key + " " + bad->problem);
  float largest = 0;
  for (float v : drr.pixels) largest = std::max(largest, v);
  const double scale = largest > p.max_line_integral ? p.max_line_integral / largest : 1.0;

  // Steps 1-3: the primary intensity, in double so that "every effect off" returns the DRR up to
  // the float rounding of the result.
  std::vector<double> primary(drr.pixels.size());
  for (size_t i = 0; i < primary.size(); ++i) {
    const double l = scale * std::max(0.0f, drr.pixels[i]);
    primary[i] = std::exp(-(l - p.beam_hardening * l * l));
  }
  std::vector<float> intensity(primary.begin(), primary.end());

  // Step 4: scatter, a wide blur of the primary (the scatter kernel of a body is broad and smooth).
  if (p.scatter_to_primary > 0) {
    const double sigma = p.scatter_sigma_px > 0 ? p.scatter_sigma_px : 40.0 * drr.width / 512.0;
    std::vector<float> scatter = intensity;
    gaussian_blur(scatter, drr.width, drr.height, sigma);
    for (size_t i = 0; i < intensity.size(); ++i) intensity[i] += float(p.scatter_to_primary) * scatter[i];
  }
  // Step 5: the detector's point-spread (scintillator and optics), on the intensity it receives.
  if (p.blur_px > 0) gaussian_blur(intensity, drr.width, drr.height, p.blur_px);

  Image out(drr.width, drr.height);
  if (p.photons > 0) {
    // Step 6: quantum noise. A pixel that counts no photon reads as half a photon, the usual
    // guard of a log transform (a real detector clips there as well).
    std::mt19937_64 rng(p.seed);
    for (size_t i = 0; i < intensity.size(); ++i) {
      std::poisson_distribution<long long> counts(p.photons * std::max(0.0f, intensity[i]));
      const double n = double(counts(rng));
      out.pixels[i] = float(-std::log(std::max(n, 0.5) / p.photons) / scale);
    }
  } else {
    for (size_t i = 0; i < intensity.size(); ++i) {
      // Without effects the primary in double gives back exactly the DRR; otherwise the float
      // intensity (blurred) is the image.
      const double v = p.scatter_to_primary > 0 || p.blur_px > 0 ? double(intensity[i]) : primary[i];
      out.pixels[i] = float(-std::log(std::max(v, 1e-30)) / scale);
    }
  }
  return out;
}

}  // namespace fluoro
