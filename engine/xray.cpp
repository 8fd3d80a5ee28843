#include "engine/xray.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdint>
#include <vector>

#include "engine/error.hpp"
#include "engine/file_names.hpp"
#include "engine/image_io.hpp"
#include "engine/spaced_image_writer.hpp"

namespace fluoro {

LogDomainMapping display_mapping(const Image& drr, double full_scale) {
  float hi = 0;
  for (float v : drr.pixels) hi = std::max(hi, v);
  return {full_scale, hi > 0 ? full_scale / hi : 1.0};
}

Image drr_to_xray(const Image& drr, const LogDomainMapping& m) {
  Image out(drr.width, drr.height);
  std::transform(drr.pixels.begin(), drr.pixels.end(), out.pixels.begin(),
                 [&](float v) { return float(m.a - m.b * v); });
  return out;
}

Image to_log_domain(Image image, XrayEncoding encoding, const std::string& what) {
  switch (encoding) {
    case XrayEncoding::log_domain:
      break;
    case XrayEncoding::bone_bright:
      for (float& v : image.pixels) v = -v;
      break;
    case XrayEncoding::linear: {
      float smallest = std::numeric_limits<float>::infinity();
      for (float v : image.pixels)
        if (v > 0) smallest = std::min(smallest, v);
      if (!std::isfinite(smallest)) throw_input_error(what, "a linear X-ray needs positive intensities (--linear)");
      for (float& v : image.pixels) v = std::log(std::max(v, smallest));
      break;
    }
  }
  return image;
}

LogDomainMapping write_drr(const Image& drr, const std::string& path, const Eigen::Vector2d& spacing_mm,
                           const Eigen::Vector2d& origin_mm) {
  if (is_spaced_image_path(path)) {
    write_spaced_image(drr, spacing_mm, origin_mm, path);
    return {0, -1};
  }
  if (is_float_image_path(path)) {
    write_float_image(drr, path);
    return {0, -1};  // the raw values: intensity = line integral
  }
  if (!ends_with(lower_file_name(path), ".png"))
    throw_input_error(path, "unsupported output format (use .png, .tif, .tiff, .pfm, .nii, .nii.gz, .mha or .nrrd)");
  const LogDomainMapping m = display_mapping(drr, 65535.0);
  const Image x = drr_to_xray(drr, m);
  std::vector<uint16_t> u16(x.pixels.size());
  std::transform(x.pixels.begin(), x.pixels.end(), u16.begin(),
                 [](float v) { return uint16_t(std::clamp(v + 0.5f, 0.0f, 65535.0f)); });
  write_png_u16(u16, drr.width, drr.height, path);
  return m;
}

}  // namespace fluoro
