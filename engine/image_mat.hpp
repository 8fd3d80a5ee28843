#pragma once
// An image seen as an OpenCV matrix without a copy: one channel of the pixel type over the
// image's own pixels (both are row-major with row 0 at the top). The matrix is valid while the
// image lives and keeps its size. OpenCV has no read-only matrix, so the view of a const image is
// for reading only: clone() it before anything writes.
#include <opencv2/core.hpp>

#include "engine/image.hpp"

namespace fluoro {

template <class T>
cv::Mat mat_view(ImageT<T>& image) {
  return cv::Mat(image.height, image.width, cv::DataType<T>::type, image.pixels.data());
}

template <class T>
cv::Mat mat_view(const ImageT<T>& image) {
  return cv::Mat(image.height, image.width, cv::DataType<T>::type, const_cast<T*>(image.pixels.data()));
}

}  // namespace fluoro
