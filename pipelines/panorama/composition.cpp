#include "pipelines/panorama/panorama.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "engine/field_of_view.hpp"


namespace fluoro {

cv::Mat compose_panorama(const std::vector<cv::Mat>& images, const Panorama& p, PanoramaBlend blend) {
  struct Warped { cv::Rect roi; cv::Mat image, mask; };
  std::vector<Warped> warped;
  for (size_t i = 0; i < images.size(); ++i) {
    if (!p.frames[i].aligned) continue;
    cv::Mat img;
    images[i].convertTo(img, CV_32F);
    const cv::Mat mask = field_of_view_mask(img, 2);
    const Eigen::Matrix3d& H = p.frames[i].H_panorama_frame;
    Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
    for (const auto& [u, v] : {std::pair{0, 0}, {img.cols - 1, 0}, {0, img.rows - 1}, {img.cols - 1, img.rows - 1}}) {
      const Eigen::Vector2d q = (H * Eigen::Vector3d(u, v, 1)).head<2>();
      lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
    }
    cv::Rect roi(int(std::floor(lo.x())), int(std::floor(lo.y())), 0, 0);
    roi.width = int(std::ceil(hi.x())) - roi.x + 1, roi.height = int(std::ceil(hi.y())) - roi.y + 1;
    roi &= cv::Rect(0, 0, p.width, p.height);
    cv::Mat m = (cv::Mat_<double>(2, 3) << H(0, 0), H(0, 1), H(0, 2) - roi.x, H(1, 0), H(1, 1), H(1, 2) - roi.y);
    Warped w;
    w.roi = roi;
    cv::warpAffine(img, w.image, m, roi.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
    cv::warpAffine(mask, w.mask, m, roi.size(), cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(0));
    warped.push_back(std::move(w));
  }
  cv::Mat out = cv::Mat::zeros(p.height, p.width, CV_32F);
  tbb::parallel_for(tbb::blocked_range<int>(0, p.height), [&](const tbb::blocked_range<int>& rows) {
    std::vector<float> values;
    std::vector<const Warped*> here;
    for (int y = rows.begin(); y < rows.end(); ++y) {
      here.clear();  // the frames whose box holds this row
      for (const Warped& w : warped)
        if (y >= w.roi.y && y < w.roi.y + w.roi.height) here.push_back(&w);
      for (int x = 0; x < p.width; ++x) {
        values.clear();
        for (const Warped* wp : here) {
          const Warped& w = *wp;
          const int lx = x - w.roi.x, ly = y - w.roi.y;
          if (lx < 0 || ly < 0 || lx >= w.roi.width || ly >= w.roi.height || !w.mask.at<uint8_t>(ly, lx)) continue;
          values.push_back(w.image.at<float>(ly, lx));
        }
        if (values.empty()) continue;
        float v = values[0];
        switch (blend) {
          case PanoramaBlend::Max: v = *std::max_element(values.begin(), values.end()); break;
          case PanoramaBlend::Min: v = *std::min_element(values.begin(), values.end()); break;
          case PanoramaBlend::Mean: {
            double s = 0;
            for (float q : values) s += q;
            v = float(s / double(values.size()));
            break;
          }
          case PanoramaBlend::Median: {
            std::sort(values.begin(), values.end());
            const size_t h = values.size() / 2;
            v = values.size() % 2 ? values[h] : 0.5f * (values[h - 1] + values[h]);
            break;
          }
        }
        out.at<float>(y, x) = v;
      }
    }
  });
  return out;
}

}  // namespace fluoro
