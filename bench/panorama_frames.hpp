#pragma once
// The generated set's 16-bit frames as the float images align_panorama takes (shared by the
// panorama bench's modes).
#include <opencv2/core.hpp>
#include <vector>

#include "datasets/panorama_scene.hpp"
#include "engine/image_mat.hpp"

namespace fluoro {

inline std::vector<cv::Mat> frames_of(const PanoramaScene& s) {
  std::vector<cv::Mat> out;
  for (const auto& im : s.images) {
    cv::Mat f;
    mat_view(im).convertTo(f, CV_32F);
    out.push_back(f);
  }
  return out;
}

}  // namespace fluoro
