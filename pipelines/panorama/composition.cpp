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
  std::vector<size_t> aligned;
  for (size_t i = 0; i < images.size(); ++i)
    if (p.frames[i].aligned) aligned.push_back(i);
  std::vector<Warped> warped(aligned.size());
  tbb::parallel_for(size_t(0), aligned.size(), [&](size_t k) {
    const size_t i = aligned[k];
    cv::Mat img;
    images[i].convertTo(img, CV_32F);
    const cv::Mat mask = p.field_masks.size() == images.size() ? p.field_masks[i] : field_of_view_mask(img, 2);
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
    warped[k] = std::move(w);
  });
  cv::Mat out = cv::Mat::zeros(p.height, p.width, CV_32F);
  if (blend != PanoramaBlend::Median) {
    // Frame by frame (in order) over its box only: where no frame was yet, its pixels; where some
    // were, the running max / min / sum. The same values as the per-pixel rule below, without a
    // loop over every frame at every panorama pixel; panorama rows in parallel.
    const bool mean = blend == PanoramaBlend::Mean;
    tbb::parallel_for(tbb::blocked_range<int>(0, p.height), [&](const tbb::blocked_range<int>& rows) {
      std::vector<int> count(static_cast<size_t>(p.width));     // frames seen at each pixel of the row
      std::vector<double> total(mean ? size_t(p.width) : 0);  // their sum, in double as the rule below
      for (int y = rows.begin(); y < rows.end(); ++y) {
        float* o = out.ptr<float>(y);
        std::fill(count.begin(), count.end(), 0);
        std::fill(total.begin(), total.end(), 0.0);
        int* c = count.data();
        double* s = mean ? total.data() : nullptr;
        for (const Warped& w : warped) {
          if (y < w.roi.y || y >= w.roi.y + w.roi.height) continue;
          const float* v = w.image.ptr<float>(y - w.roi.y);
          const uint8_t* m = w.mask.ptr<uint8_t>(y - w.roi.y);
          for (int lx = 0; lx < w.roi.width; ++lx) {
            if (!m[lx]) continue;
            const int x = lx + w.roi.x;
            if (s) s[x] += double(v[lx]);
            else if (c[x] == 0) o[x] = v[lx];
            else o[x] = blend == PanoramaBlend::Max ? std::max(o[x], v[lx]) : std::min(o[x], v[lx]);
            ++c[x];
          }
        }
        if (s)
          for (int x = 0; x < p.width; ++x)
            if (c[x] > 0) o[x] = float(s[x] / double(c[x]));
      }
    });
    return out;
  }
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
