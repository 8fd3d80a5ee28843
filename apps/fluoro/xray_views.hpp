#pragma once
// --view XRAY:CAMERA arguments: X-ray images read per the conventions and their cameras.
#include <string>
#include <utility>
#include <vector>

#include "engine/xray.hpp"
#include "pipelines/registration/registration.hpp"

namespace fluoro::cli {

// "image.png:camera.json" -> {image, camera}, split at the last ':'. InputError when malformed.
std::pair<std::string, std::string> split_view_argument(const std::string& arg);

// Reads each view's image (to the log domain) and camera. Throws InputError naming the file for
// an unreadable file, or an image whose size differs from its camera's.
std::vector<XrayView> read_xray_views(const std::vector<std::string>& args, XrayEncoding encoding);

}  // namespace fluoro::cli
