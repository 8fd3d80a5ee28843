#pragma once
// Penney et al.'s gradient correlation of an X-ray with a DRR, corrected for the X-ray's noise.
//
// The correlation of two images is the mean, over x and y, of the normalised cross-correlations
// of their derivatives. Detector noise in the X-ray lowers it by a known factor: the DRR is
// noise-free, so corr(a + n, b) = corr(a, b) * sqrt(var a / (var a + var n)) (the classical
// correction for attenuation). Dividing by that factor makes the value a property of the pose and
// the anatomy, not of the detector's dose: a threshold calibrated on clean views then holds on
// noisy ones. The noise is estimated from the X-ray itself (white noise assumed).
#include <opencv2/core.hpp>

namespace fluoro {

class XrayGradients {
 public:
  // `xray`: the X-ray at the size the DRRs will have (one channel, log domain: bone dark). Both images
  // are smoothed by a Gaussian of blur_px before differentiating. `correct_noise` false: no noise
  // estimate and no correction (for a noise-free image, such as a DRR standing in for an X-ray,
  // whose fine detail the estimate would mistake for noise).
  XrayGradients(const cv::Mat& xray, double blur_px, bool correct_noise = true);

  // The noise-corrected gradient correlation with `drr` (same size; bone bright), in [-1, 1]. An
  // axis along which either image is flat contributes 0 (a blank DRR scores 0, not a match).
  // correlate(derivatives(drr)).
  double correlate(const cv::Mat& drr) const;

  // The same from a DRR's derivatives (derivatives(), computed once when one DRR is compared with
  // several X-rays), by direct sums.
  struct Derivatives {
    cv::Mat d[2];  // smoothed x and y derivatives (CV_32F)
    // Their means and centred sums of squares, computed once: one DRR is correlated with several
    // images (the confidence check: the X-ray and the DRR at the result).
    double mean[2] = {0, 0}, centred_squares[2] = {0, 0};
  };
  Derivatives derivatives(const cv::Mat& drr) const;
  double correlate(const Derivatives& drr) const;
  // The noise-free X-ray that a DRR stands in for (minus the DRR: bone dark), from the DRR's
  // derivatives(): the same, bit for bit, as XrayGradients(-drr, blur_px, false) with this object's
  // blur, without smoothing and differentiating the DRR again (the derivatives are linear, and
  // rounding is symmetric under negation).
  XrayGradients drr_as_xray(const Derivatives& drr) const;

  // The X-ray's estimated noise (standard deviation, in its own units) and, per axis, the share
  // of its derivative's variance that is signal (1 for a clean image; at least kMinSignalShare).
  double noise_sigma() const { return noise_sigma_; }
  double blur_px() const { return blur_px_; }
  double signal_share(int axis) const { return signal_share_[axis]; }

  // Below this share the correction would mostly amplify guesswork (fine texture, grid lines or
  // edge enhancement look like white noise to the estimate, and inflating a correlation is the
  // unsafe direction): the correction stops at a factor of sqrt(2).
  static constexpr double kMinSignalShare = 0.5;

 private:
  explicit XrayGradients(double blur_px) : blur_px_(blur_px) {}
  double blur_px_;
  cv::Mat minus_derivative_[2];  // minus the smoothed X-ray's x and y derivatives
  double mean_[2] = {0, 0}, centred_squares_[2] = {0, 0};  // of minus_derivative_, for correlate(Derivatives)
  double noise_sigma_ = 0;
  double signal_share_[2] = {1, 1};
  bool flat_[2] = {false, false};  // the X-ray has no variation along that axis
};

// Standard deviation of white noise in `image`, robustly: the median absolute residual of a
// 1-pixel Gaussian blur (edges and texture are few, so the median sees mostly noise), scaled by
// the residual filter's noise gain.
double estimate_white_noise_sigma(const cv::Mat& image);

}  // namespace fluoro
