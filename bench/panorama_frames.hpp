#pragma once
// The generated set's 16-bit frames as the float images align_panorama takes (shared by the
// panorama bench's modes).
#include <opencv2/core.hpp>
#include <vector>

#include "datasets/panorama_scene.hpp"

namespace fluoro {

inline std::vector<cv::Mat> frames_of(const PanoramaScene& s) {
  std::vector<cv::Mat> out;
  for (const auto& im : s.images) {
    cv::Mat f;
    cv::Mat(im.height, im.width, CV_16U, const_cast<uint16_t*>(im.pixels.data())).convertTo(f, CV_32F);
    out.push_back(f);
  }
  return out;
}

}  // namespace fluoro
