#pragma once
// Erosion of a binary mask by OpenCV's elliptic structuring element, without OpenCV's cost.
// cv::erode visits every point of a non-rectangular element at every pixel: a 41 x 41 ellipse is
// about 1,300 comparisons per pixel, and it was the largest single cost of the panorama's
// band-pass. The ellipse is a stack of centred horizontal runs, so a pixel survives exactly when,
// on each row of the element, the mask's run of inside pixels through that column reaches the
// run's half-width on both sides: one comparison per element row. Elements under 25 x 25 go to
// cv::erode, faster there.
#include <opencv2/core.hpp>

namespace fluoro {

// The same pixels as cv::erode(mask, out, cv::getStructuringElement(cv::MORPH_ELLIPSE,
// {diameter, diameter}), {-1, -1}, 1, cv::BORDER_CONSTANT, 0) for an 8-bit mask whose pixels are 0
// or 255 (outside the image counts as outside the mask); 255 inside. `diameter` odd, >= 1.
cv::Mat erode_ellipse(const cv::Mat& mask, int diameter);

}  // namespace fluoro
