// erode_ellipse against cv::erode with OpenCV's elliptic element: the same pixels on masks with
// discs, holes, thin lines and noise touching the image border, for small and large elements.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "engine/ellipse_erosion.hpp"

namespace fluoro {
namespace {

cv::Mat test_mask(int width, int height, uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat m = cv::Mat::zeros(height, width, CV_8U);
  cv::circle(m, {width / 2, height / 2}, int(0.45 * std::min(width, height)), cv::Scalar(255), cv::FILLED);
  cv::rectangle(m, {0, 0}, {width / 3, height / 4}, cv::Scalar(255), cv::FILLED);  // touches the border
  for (int k = 0; k < 12; ++k) {
    const cv::Point a(rng.uniform(0, width), rng.uniform(0, height)), b(rng.uniform(0, width), rng.uniform(0, height));
    cv::line(m, a, b, cv::Scalar(k % 2 ? 255 : 0), rng.uniform(1, 6));
    cv::circle(m, b, rng.uniform(1, 25), cv::Scalar(k % 3 ? 0 : 255), cv::FILLED);
  }
  for (int k = 0; k < 300; ++k) m.at<uint8_t>(rng.uniform(0, height), rng.uniform(0, width)) ^= 255;  // salt and pepper
  return m;
}

TEST(EllipseErosion, SameAsOpenCvErode) {
  for (const cv::Size size : {cv::Size(257, 190), cv::Size(64, 300), cv::Size(9, 7)})
    for (const int d : {1, 3, 5, 13, 25, 27, 41, 61}) {  // from 25 on, erode_ellipse's own rows
      const cv::Mat m = test_mask(size.width, size.height, uint64_t(d * 1000 + size.width));
      cv::Mat expected;
      cv::erode(m, expected, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(d, d)), cv::Point(-1, -1), 1,
                cv::BORDER_CONSTANT, cv::Scalar(0));
      const cv::Mat got = erode_ellipse(m, d);
      ASSERT_EQ(got.type(), CV_8U);
      EXPECT_EQ(cv::countNonZero(got != expected), 0) << "diameter " << d << ", image " << size;
      if (d == 13 && size.width == 257) {
        EXPECT_GT(cv::countNonZero(got), 1000);  // not trivially empty
      }
    }
}

TEST(EllipseErosion, RefusesEvenDiameterAndOtherTypes) {
  EXPECT_THROW(erode_ellipse(cv::Mat::zeros(10, 10, CV_8U), 4), std::invalid_argument);
  EXPECT_THROW(erode_ellipse(cv::Mat::zeros(10, 10, CV_32F), 3), std::invalid_argument);
}

}  // namespace
}  // namespace fluoro
