#pragma once
// The exposed region of a fluoroscopic frame: the circular (or any) field of view, black outside.
#include <opencv2/core.hpp>

namespace fluoro {

// 8-bit mask (255 inside) of the pixels exposed by the X-ray: brighter than the dark surround by a
// small fraction of the image's range, holes filled, eroded by `erode_px` so that the soft rim and
// the blur at the boundary never count as image content. A frame with no dark surround is all 255.
cv::Mat field_of_view_mask(const cv::Mat& image, int erode_px = 3);

}  // namespace fluoro
