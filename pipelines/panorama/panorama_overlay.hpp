#pragma once
// A picture to check a panorama by eye (issue 11, `fluoro panorama --overlay`): the panorama in
// grey, each frame's ruler thread in red, the graduations it found as green ticks across the
// thread, and the outline of every frame's field of view (where its seams with the others lie) in
// cyan.
#include <opencv2/core.hpp>
#include <vector>

#include "pipelines/panorama/panorama.hpp"

namespace fluoro {

// CV_8UC3 (BGR, as cv::imwrite expects) of the panorama's size. `frames` are the corrected frames
// the panorama was composed from (their fields of view give the seams); `panorama_image` is
// compose_panorama's result. Grey levels span the 1st to 99th percentile of the covered pixels.
cv::Mat panorama_overlay(const cv::Mat& panorama_image, const std::vector<cv::Mat>& frames, const Panorama& panorama);

}  // namespace fluoro
