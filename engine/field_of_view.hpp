#pragma once
// The exposed region of a fluoroscopic image: the image intensifier's round field of view (or a
// collimator's), black around it. Detectors look for features inside it, judge edges against what
// is inside it rather than its rim, and count what it could show.
#include <opencv2/core.hpp>
#include <vector>

namespace fluoro {

// 8-bit mask (255 inside) of the exposed pixels: after a 5x5 median (noise and dust do not punch
// holes in it), the pixels above 5 % of the way from the darkest level to the 99th percentile; the
// largest such region with its holes filled (dark metal inside the field stays inside), eroded by
// `erode_px` so that the soft rim never counts as image content. Any single-channel depth. An image
// without a dark surround is all 255; a flat image is all 0.
cv::Mat field_of_view_mask(const cv::Mat& image, int erode_px = 0);

// The q-quantile (0..1) of the values, by partial sorting of a copy; 0 for none.
double percentile(std::vector<float> values, double q);

}  // namespace fluoro
