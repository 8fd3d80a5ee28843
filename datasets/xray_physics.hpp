#pragma once
// A simulator of the imaging physics a DRR leaves out (issue 14, item 3): beam hardening, scatter,
// detector blur and quantum noise. It turns a DRR (line integrals of attenuation, the project's
// convention, docs/conventions.md "DRR values") into the line-integral image a real C-arm would
// give after its log transform, so that registration can be tested on X-rays that do not follow
// its own model. Each effect is off by default and set by one number.
//
// The chain, per pixel (L = the DRR's line integral):
//   1. scale:          l = s L with s = min(1, max_line_integral / max L): keeps the beam-hardening
//                      curve in its monotonic range (the "mu*L <= 6")
//   2. beam hardening: l_eff = l - b l^2 (a polychromatic beam attenuates less per unit of
//                      thickness as it hardens; b ~ 0.06 fits a 70 kVp spectrum through bone and water)
//   3. primary:        P = exp(-l_eff) (intensity relative to the unattenuated beam)
//   4. scatter:        I = P + SPR * G_wide * P (G_wide: a Gaussian of scatter_sigma_px, default
//                      40 px at 512 pixels a side, scaled with the width); a flat field gains (1 + SPR)
//   5. detector blur:  I = G_blur * I
//   6. quantum noise:  counts ~ Poisson(N I), I = counts / N (N photons per pixel of open beam)
//   7. log:            out = -log(I) / s (back to the DRR's units: with every effect off, out = L)
// The flat-field correction of a real detector is made without the patient, so the scatter the
// patient adds stays in the image (air reads -log(1 + SPR) < 0, not 0).
#include <cstdint>
#include <optional>
#include <string>

#include "engine/image.hpp"

namespace fluoro {

struct XrayPhysics {
  double max_line_integral = 6;   // step 1: the largest mu*L after scaling
  double beam_hardening = 0;      // step 2: b, per unit of scaled line integral; 0: monochromatic
  double scatter_to_primary = 0;  // step 4: SPR of a flat field; 0: no scatter
  double scatter_sigma_px = 0;    // step 4: the scatter kernel's sigma; 0: 40 px x width / 512
  double blur_px = 0;             // step 5: detector blur sigma in pixels; 0: none
  double photons = 0;             // step 6: photons per open-beam pixel; 0: no noise
  uint64_t seed = 1;              // step 6: the noise's seed (same seed, same image)

  // True when any effect is on (a scale alone changes nothing).
  bool any() const { return beam_hardening > 0 || scatter_to_primary > 0 || blur_px > 0 || photons > 0; }
};

// The largest beam-hardening coefficient for which l - b l^2 still grows up to max_line_integral
// (b <= 1 / (2 max)): beyond it thicker would look thinner.
double largest_beam_hardening(const XrayPhysics& p);

// What is wrong with a parameter, if anything: a value out of range (negative, NaN, a beam-hardening
// coefficient beyond largest_beam_hardening, under one photon). `key` is the parameter's name in
// SWEEP.json's "physics" (beam_hardening, scatter, scatter_sigma_px, blur_px, photons,
// max_line_integral), so that a caller can name its own option.
struct XrayPhysicsProblem {
  std::string key, problem;
};
std::optional<XrayPhysicsProblem> xray_physics_problem(const XrayPhysics& p);

// The DRR as the physics above would image it, in the DRR's units. Deterministic for a seed.
// Throws InputError for parameters with a problem.
Image simulate_xray_physics(const Image& drr, const XrayPhysics& p);

}  // namespace fluoro
