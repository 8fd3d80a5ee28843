#include "pipelines/registration/gradient_correlation.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace fluoro {
namespace {

// Sum of squares of a linear filter's impulse response: the factor by which it scales the
// variance of white noise. The filter is applied to a unit impulse in a zero image.
// `reach_px`: how far the response can spread; the impulse image is large enough that none of it
// folds back at the border.
template <class Filter>
double noise_gain(double reach_px, Filter&& filter) {
  const int half = int(std::ceil(reach_px)) + 4;
  cv::Mat delta = cv::Mat::zeros(2 * half + 1, 2 * half + 1, CV_32F), out;
  delta.at<float>(half, half) = 1.0f;
  filter(delta, out);
  return cv::sum(out.mul(out))[0];
}

void smooth(const cv::Mat& in, cv::Mat& out, double blur_px) {
  if (blur_px > 0) cv::GaussianBlur(in, out, cv::Size(0, 0), blur_px);
  else out = in.clone();
}

void derivative(const cv::Mat& in, cv::Mat& out, int axis) { cv::Sobel(in, out, CV_32F, axis == 0, axis == 1, 3); }

double variance(const cv::Mat& m) {
  cv::Scalar mean, dev;
  cv::meanStdDev(m, mean, dev);
  return dev[0] * dev[0];
}

}  // namespace

double estimate_white_noise_sigma(const cv::Mat& input) {
  cv::Mat image, smooth_image, residual;
  input.convertTo(image, CV_32F);
  smooth(image, smooth_image, 1.0);
  cv::absdiff(image, smooth_image, residual);
  std::vector<float> v(residual.begin<float>(), residual.end<float>());
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + std::ptrdiff_t(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  const double gain = noise_gain(4.0, [](const cv::Mat& d, cv::Mat& out) {
    cv::Mat s;
    smooth(d, s, 1.0);
    out = d - s;
  });
  return 1.4826 * double(*mid) / std::sqrt(gain);
}

XrayGradients::XrayGradients(const cv::Mat& input, double blur_px, bool correct_noise) : blur_px_(blur_px) {
  cv::Mat xray, s;
  input.convertTo(xray, CV_32F);
  noise_sigma_ = correct_noise ? estimate_white_noise_sigma(xray) : 0.0;
  smooth(xray, s, blur_px_);
  for (int axis = 0; axis < 2; ++axis) {
    cv::Mat d;
    derivative(s, d, axis);
    // The X-ray darkens where the DRR grows: correlate with minus its derivative.
    minus_derivative_[axis] = -d;
    const double gain = noise_gain(4.0 * blur_px_, [&](const cv::Mat& delta, cv::Mat& out) {
      cv::Mat t;
      smooth(delta, t, blur_px_);
      derivative(t, out, axis);
    });
    const double total = variance(d), noise = noise_sigma_ * noise_sigma_ * gain;
    flat_[axis] = !(total > 0);
    signal_share_[axis] = flat_[axis] ? 1.0 : std::clamp(1.0 - noise / total, kMinSignalShare, 1.0);
  }
}

double XrayGradients::correlate(const cv::Mat& input) const {
  cv::Mat drr = input, s;
  if (input.type() != CV_32F) input.convertTo(drr, CV_32F);
  smooth(drr, s, blur_px_);
  double gc = 0;
  for (int axis = 0; axis < 2; ++axis) {
    cv::Mat d, r;
    derivative(s, d, axis);
    // A flat image correlates with nothing (OpenCV would call a flat template a perfect match,
    // 1): a DRR in which the bone is out of view must not pass for a registered one.
    if (flat_[axis] || !(variance(d) > 0)) continue;
    cv::matchTemplate(minus_derivative_[axis], d, r, cv::TM_CCOEFF_NORMED);
    gc += 0.5 * std::clamp(double(r.at<float>(0, 0)) / std::sqrt(signal_share_[axis]), -1.0, 1.0);
  }
  return gc;
}

XrayGradients::Derivatives XrayGradients::derivatives(const cv::Mat& input) const {
  cv::Mat drr = input, s;
  if (input.type() != CV_32F) input.convertTo(drr, CV_32F);
  smooth(drr, s, blur_px_);
  Derivatives out;
  for (int axis = 0; axis < 2; ++axis) derivative(s, out.d[axis], axis);
  return out;
}

double XrayGradients::correlate(const Derivatives& drr) const {
  double gc = 0;
  for (int axis = 0; axis < 2; ++axis) {
    const cv::Mat& a = minus_derivative_[axis];
    const cv::Mat& b = drr.d[axis];
    if (flat_[axis] || a.size() != b.size()) continue;
    // The normalised cross-correlation (TM_CCOEFF_NORMED of two images of one size), in double.
    const double n = double(a.total()), ma = cv::mean(a)[0], mb = cv::mean(b)[0];
    const double sab = a.dot(b) - n * ma * mb, saa = a.dot(a) - n * ma * ma, sbb = b.dot(b) - n * mb * mb;
    if (!(saa > 0) || !(sbb > 0)) continue;
    gc += 0.5 * std::clamp(sab / std::sqrt(saa * sbb) / std::sqrt(signal_share_[axis]), -1.0, 1.0);
  }
  return gc;
}

}  // namespace fluoro
