#include "engine/ellipse_erosion.hpp"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

namespace fluoro {

namespace {

// reach(y, x): how many inside pixels run from x to the left and to the right, the smaller count
// (0 outside the mask), saturated at T's maximum (more than any half-width). Run [x - w, x + w] is
// inside exactly when reach > w. A pixel survives when that holds on every element row; only the
// columns where every row involved has some inside pixel need the test (8-bit counts when the
// element allows: twice the pixels per vector instruction).
template <typename T>
cv::Mat erode_rows(const cv::Mat& mask, const std::vector<int>& half) {
  const int W = mask.cols, H = mask.rows, diameter = int(half.size()), r = diameter / 2;
  constexpr int kMax = std::numeric_limits<T>::max();
  std::vector<T> reach(size_t(W) * size_t(H));
  std::vector<T> left(static_cast<size_t>(W));
  std::vector<int> first(static_cast<size_t>(H), W), last(static_cast<size_t>(H), -1);  // nonzero columns per row
  for (int y = 0; y < H; ++y) {
    const uint8_t* m = mask.ptr<uint8_t>(y);
    T* out = reach.data() + size_t(y) * size_t(W);
    int run = 0;
    for (int x = 0; x < W; ++x) left[size_t(x)] = T(run = m[x] ? std::min(kMax, run + 1) : 0);
    run = 0;
    for (int x = W - 1; x >= 0; --x) {
      run = m[x] ? std::min(kMax, run + 1) : 0;
      out[x] = std::min(T(run), left[size_t(x)]);
      if (run) first[size_t(y)] = x, last[size_t(y)] = std::max(last[size_t(y)], x);
    }
  }
  cv::Mat eroded = cv::Mat::zeros(H, W, CV_8U);
  for (int y = 0; y < H; ++y) {
    int x0 = 0, x1 = W - 1;
    for (int i = 0; i < diameter; ++i) {
      if (half[size_t(i)] < 0) continue;
      const int row = y + i - r;
      if (row < 0 || row >= H) x0 = W, x1 = -1;  // rows beyond the image are outside
      else x0 = std::max(x0, first[size_t(row)]), x1 = std::min(x1, last[size_t(row)]);
    }
    if (x0 > x1) continue;
    uint8_t* out = eroded.ptr<uint8_t>(y);
    std::fill(out + x0, out + x1 + 1, uint8_t(255));
    for (int i = 0; i < diameter; ++i) {
      if (half[size_t(i)] < 0) continue;
      const T* q = reach.data() + size_t(y + i - r) * size_t(W);
      const T w = T(half[size_t(i)]);
      for (int x = x0; x <= x1; ++x) out[x] = q[x] > w ? out[x] : uint8_t(0);
    }
  }
  return eroded;
}

}  // namespace

cv::Mat erode_ellipse(const cv::Mat& mask, int diameter) {
  if (mask.type() != CV_8UC1 || diameter < 1 || diameter % 2 == 0)
    throw std::invalid_argument("erode_ellipse: an 8-bit single-channel mask and an odd diameter");
  const int r = diameter / 2;
  // Small elements: cv::erode itself is faster (a 1024^2 disc mask, one core: 0.2 ms at 5 x 5,
  // 1.2 ms at 13 x 13, against about 3.5 ms here whatever the size, mostly the run counts; 13.7 ms
  // for cv::erode at 41 x 41).
  if (diameter < 25) {
    cv::Mat eroded;
    cv::erode(mask, eroded, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(diameter, diameter)), cv::Point(-1, -1), 1,
              cv::BORDER_CONSTANT, cv::Scalar(0));
    return eroded;
  }
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
  const int widest = *std::max_element(half.begin(), half.end());
  return widest < 255 ? erode_rows<uint8_t>(mask, half) : erode_rows<uint16_t>(mask, half);
}

}  // namespace fluoro
