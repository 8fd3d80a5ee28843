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

// sum (m - mean)^2, as m . m - n mean^2 (the normalised cross-correlation's denominator terms).
double centred_sum_of_squares(const cv::Mat& m, double mean) { return m.dot(m) - double(m.total()) * mean * mean; }

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
    mean_[axis] = cv::mean(minus_derivative_[axis])[0];
    centred_squares_[axis] = centred_sum_of_squares(minus_derivative_[axis], mean_[axis]);
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

double XrayGradients::correlate(const cv::Mat& input) const { return correlate(derivatives(input)); }

XrayGradients XrayGradients::drr_as_xray(const Derivatives& drr) const {
  // The X-ray -drr has derivatives -d, so minus its derivatives are the DRR's own; no noise.
  XrayGradients x(blur_px_);
  for (int axis = 0; axis < 2; ++axis) {
    x.minus_derivative_[axis] = drr.d[axis];
    x.mean_[axis] = drr.mean[axis];
    x.centred_squares_[axis] = drr.centred_squares[axis];
    x.flat_[axis] = !(variance(drr.d[axis]) > 0);
  }
  return x;
}

XrayGradients::Derivatives XrayGradients::derivatives(const cv::Mat& input) const {
  cv::Mat drr = input, s;
  if (input.type() != CV_32F) input.convertTo(drr, CV_32F);
  smooth(drr, s, blur_px_);
  Derivatives out;
  for (int axis = 0; axis < 2; ++axis) {
    derivative(s, out.d[axis], axis);
    out.mean[axis] = cv::mean(out.d[axis])[0];
    out.centred_squares[axis] = centred_sum_of_squares(out.d[axis], out.mean[axis]);
  }
  return out;
}

double XrayGradients::correlate(const Derivatives& drr) const {
  double gc = 0;
  for (int axis = 0; axis < 2; ++axis) {
    const cv::Mat& a = minus_derivative_[axis];
    const cv::Mat& b = drr.d[axis];
    if (flat_[axis] || a.size() != b.size()) continue;
    // The normalised cross-correlation of two images of one size (matchTemplate's TM_CCOEFF_NORMED,
    // which computed it by DFTs, several times slower: docs/benchmarks.md, "Direct sums"), by direct
    // sums in double; only the cross term is new for each pair.
    const double n = double(a.total()), ma = mean_[axis], mb = drr.mean[axis];
    const double sab = a.dot(b) - n * ma * mb, saa = centred_squares_[axis], sbb = drr.centred_squares[axis];
    // A flat image correlates with nothing (matchTemplate would call a flat template a perfect
    // match, 1): a DRR in which the bone is out of view must not pass for a registered one.
    if (!(saa > 0) || !(sbb > 0)) continue;
    gc += 0.5 * std::clamp(sab / std::sqrt(saa * sbb) / std::sqrt(signal_share_[axis]), -1.0, 1.0);
  }
  return gc;
}

}  // namespace fluoro
