#include "engine/ellipse_erosion.hpp"

#include <algorithm>
#include <cstdint>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

namespace fluoro {

cv::Mat erode_ellipse(const cv::Mat& mask, int diameter) {
  if (mask.type() != CV_8UC1 || diameter < 1 || diameter % 2 == 0)
    throw std::invalid_argument("erode_ellipse: an 8-bit single-channel mask and an odd diameter");
  const int r = diameter / 2, W = mask.cols, H = mask.rows;
  // The element's rows as half-widths, read from OpenCV's own element so both agree by construction.
  const cv::Mat element = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(diameter, diameter));
  std::vector<int> half(size_t(diameter), -1);  // -1: an empty row
  for (int i = 0; i < diameter; ++i) {
    const uint8_t* e = element.ptr<uint8_t>(i);
    int first = -1, last = -1;
    for (int j = 0; j < diameter; ++j)
      if (e[j]) last = j, first = first < 0 ? j : first;
    if (first < 0) continue;
    for (int j = first; j <= last; ++j)
      if (!e[j] || r - first != last - r) throw std::logic_error("erode_ellipse: element row not a centred run");
    half[size_t(i)] = r - first;
  }
  // reach(y, x): how many inside pixels run from x to the left and to the right, the smaller count
  // (0 outside the mask). Run [x - w, x + w] is inside exactly when reach > w.
  cv::Mat reach(H, W, CV_16U);
  std::vector<uint16_t> left(static_cast<size_t>(W));
  for (int y = 0; y < H; ++y) {
    const uint8_t* m = mask.ptr<uint8_t>(y);
    uint16_t* out = reach.ptr<uint16_t>(y);
    uint16_t run = 0;
    for (int x = 0; x < W; ++x) left[size_t(x)] = run = m[x] ? uint16_t(std::min(65535, run + 1)) : uint16_t(0);
    run = 0;
    for (int x = W - 1; x >= 0; --x) {
      run = m[x] ? uint16_t(std::min(65535, run + 1)) : uint16_t(0);
      out[x] = std::min(run, left[size_t(x)]);
    }
  }
  cv::Mat eroded = cv::Mat::zeros(H, W, CV_8U);
  for (int y = 0; y < H; ++y) {
    uint8_t* out = eroded.ptr<uint8_t>(y);
    bool inside = true;
    for (int i = 0; i < diameter && inside; ++i)
      if (half[size_t(i)] >= 0 && (y + i - r < 0 || y + i - r >= H)) inside = false;  // rows beyond the image
    if (!inside) continue;
    std::fill(out, out + W, uint8_t(255));
    for (int i = 0; i < diameter; ++i) {
      if (half[size_t(i)] < 0) continue;
      const uint16_t* q = reach.ptr<uint16_t>(y + i - r);
      const uint16_t w = uint16_t(half[size_t(i)]);
      for (int x = 0; x < W; ++x) out[x] = q[x] > w ? out[x] : uint8_t(0);
    }
  }
  return eroded;
}

}  // namespace fluoro
