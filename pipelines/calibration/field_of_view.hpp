#pragma once
// The image intensifier's field of view: the round region it lights, black around it. Detectors
// look for features inside it and judge edges against what is inside it, not against its rim.
#include <opencv2/core.hpp>
#include <vector>

#include "engine/image.hpp"

namespace fluoro {

// The pixels above 5 % of the way from the image's darkest level to its 99th percentile, after a
// 5x5 median (noise and dust do not punch holes in it): 255 inside, 0 outside (CV_8U). An image
// without a dark surround is inside everywhere; a flat image is outside everywhere.
cv::Mat field_of_view_mask(const Image& image);

// The q-quantile (0..1) of the values, by partial sorting of a copy; 0 for none.
double percentile(std::vector<float> values, double q);

}  // namespace fluoro
