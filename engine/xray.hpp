#pragma once
// DRR values and X-ray intensities (docs/conventions.md, "Images"): a default input X-ray is in
// the log domain, intensity = a - b * line_integral with b > 0 (bone dark).
#include <Eigen/Core>
#include <string>

#include "engine/image.hpp"

namespace fluoro {

struct LogDomainMapping {
  double a = 0;  // intensity of a ray through air
  double b = 1;  // intensity units per unit of line integral (> 0: bone dark)
};

// The mapping that puts [0, max_line_integral] onto [full_scale, 0].
LogDomainMapping display_mapping(const Image& drr, double full_scale);

Image drr_to_xray(const Image& drr, const LogDomainMapping& m);

// How an input X-ray's values relate to attenuation (docs/conventions.md, "Images").
enum class XrayEncoding {
  log_domain,   // a - b * line integral, b > 0: bone dark (the default)
  bone_bright,  // display-inverted: b < 0
  linear,       // raw detector intensity I0 * exp(-line integral)
};

// The image in the log domain (bone dark): bone-bright images are negated, linear ones take the
// log (values at or below zero, which a log cannot take, are clamped to the smallest positive
// value). Throws InputError naming `what` for a linear image with no positive value.
Image to_log_domain(Image image, XrayEncoding encoding, const std::string& what);

// Writes a DRR by extension: .tif/.tiff/.pfm/.nii/.nii.gz hold the raw line integrals, and so do
// .mha/.nrrd, with the detector's pixel spacing (mm, column then row pitch) and the position of
// pixel (0, 0) on the detector (origin_mm; non-zero for a window); .png holds a 16-bit log-domain
// X-ray (display_mapping with full scale 65535: air white, bone dark), which is also a valid
// default input image. Returns the mapping used for .png (identity otherwise).
LogDomainMapping write_drr(const Image& drr, const std::string& path,
                           const Eigen::Vector2d& spacing_mm = Eigen::Vector2d::Ones(),
                           const Eigen::Vector2d& origin_mm = Eigen::Vector2d::Zero());

}  // namespace fluoro
