#include "apps/fluoro/xray_views.hpp"

#include "engine/error.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"

namespace fluoro::cli {

std::pair<std::string, std::string> split_view_argument(const std::string& arg) {
  const auto colon = arg.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == arg.size())
    throw_input_error("--view " + arg, "expected XRAY:CAMERA.json");
  return {arg.substr(0, colon), arg.substr(colon + 1)};
}

std::vector<XrayView> read_xray_views(const std::vector<std::string>& args, XrayEncoding encoding) {
  std::vector<XrayView> views;
  for (const std::string& a : args) {
    const auto [image_path, camera_path] = split_view_argument(a);
    XrayView v{image_path, to_log_domain(read_image(image_path), encoding, image_path), read_camera(camera_path)};
    if (v.image.width != v.camera.width || v.image.height != v.camera.height)
      throw_input_error(image_path, "the image is " + std::to_string(v.image.width) + "x" + std::to_string(v.image.height) +
                                        " pixels but its camera " + camera_path + " says " +
                                        std::to_string(v.camera.width) + "x" + std::to_string(v.camera.height));
    views.push_back(std::move(v));
  }
  return views;
}

}  // namespace fluoro::cli
