// The noise-corrected gradient correlation against closed forms: the white-noise estimate finds a
// known sigma, and adding noise to an X-ray leaves its corrected correlation with a DRR where the
// clean X-ray's was, while the plain correlation falls.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <opencv2/imgproc.hpp>

#include "pipelines/registration/gradient_correlation.hpp"

namespace fluoro {
namespace {

// A smooth "bone" (a soft-edged ellipse with a ramp inside) on a 192^2 image, bright in a DRR.
cv::Mat bone_drr(double shift_px = 0) {
  cv::Mat m(192, 192, CV_32F);
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x) {
      const double u = (x - 96 - shift_px) / 50.0, v = (y - 90) / 30.0;
      const double r = std::sqrt(u * u + v * v);
      m.at<float>(y, x) = float((1.0 / (1.0 + std::exp((r - 1.0) * 25.0))) * (1.0 + 0.1 * u));
    }
  return m;
}

// The X-ray of the same bone (log domain, bone dark) with some anatomy the DRR lacks.
cv::Mat xray_of(const cv::Mat& drr) {
  cv::Mat x = 1.0 - drr;
  for (int y = 0; y < x.rows; ++y)
    for (int c = 0; c < x.cols; ++c) x.at<float>(y, c) += float(0.2 * std::sin(c / 17.0) * std::cos(y / 23.0));
  return x;
}

cv::Mat with_noise(const cv::Mat& m, double sigma, unsigned seed) {
  cv::Mat noise(m.size(), CV_32F);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, sigma);
  return m + noise;
}

TEST(GradientCorrelation, WhiteNoiseEstimateFindsTheKnownSigma) {
  const cv::Mat clean = xray_of(bone_drr());
  EXPECT_LT(estimate_white_noise_sigma(clean), 0.002);
  for (const double sigma : {0.01, 0.03, 0.1}) {
    const double est = estimate_white_noise_sigma(with_noise(clean, sigma, 7));
    EXPECT_NEAR(est, sigma, 0.1 * sigma) << "sigma " << sigma;
  }
}

// The plain (uncorrected) gradient correlation, straight from OpenCV, as the registration
// computed it before the correction.
double plain_correlation(const cv::Mat& xray, const cv::Mat& drr) {
  cv::Mat sa, sb;
  cv::GaussianBlur(xray, sa, cv::Size(0, 0), 1.0);
  cv::GaussianBlur(drr, sb, cv::Size(0, 0), 1.0);
  double gc = 0;
  for (int axis = 0; axis < 2; ++axis) {
    cv::Mat da, db, r;
    cv::Sobel(sa, da, CV_32F, axis == 0, axis == 1, 3);
    cv::Sobel(sb, db, CV_32F, axis == 0, axis == 1, 3);
    cv::matchTemplate(-da, db, r, cv::TM_CCOEFF_NORMED);
    gc += 0.5 * double(r.at<float>(0, 0));
  }
  return gc;
}

TEST(GradientCorrelation, NoiseDoesNotMoveTheCorrectedValue) {
  const cv::Mat drr = bone_drr(), clean = xray_of(drr);
  const XrayGradients reference(clean, 1.0);
  EXPECT_GT(reference.signal_share(0), 0.98);  // a clean image is left as it is
  EXPECT_GT(reference.signal_share(1), 0.98);
  const double at_truth = reference.correlate(drr), off = reference.correlate(bone_drr(8.0));
  EXPECT_NEAR(at_truth, plain_correlation(clean, drr), 0.01);
  EXPECT_GT(at_truth, 0.8);
  EXPECT_LT(off, at_truth - 0.2);  // the measure sees an 8-pixel shift
  for (const double sigma : {0.07, 0.1}) {
    const cv::Mat noisy_xray = with_noise(clean, sigma, 11);
    const XrayGradients noisy(noisy_xray, 1.0);
    for (int axis = 0; axis < 2; ++axis) {
      // The noise takes a real share of the derivatives' variance, within the correction's range.
      EXPECT_LT(noisy.signal_share(axis), 0.9) << "sigma " << sigma << " axis " << axis;
      EXPECT_GT(noisy.signal_share(axis), XrayGradients::kMinSignalShare) << "sigma " << sigma << " axis " << axis;
    }
    // The plain correlation loses what the corrected one keeps.
    EXPECT_LT(plain_correlation(noisy_xray, drr), at_truth - 0.05) << "sigma " << sigma;
    EXPECT_NEAR(noisy.correlate(drr), at_truth, 0.03) << "sigma " << sigma;
    EXPECT_NEAR(noisy.correlate(bone_drr(8.0)), off, 0.05) << "sigma " << sigma;
  }
}

// The direct sums in double (the registration's) against OpenCV's normalised cross-correlation of
// the derivatives, without the noise correction: equal up to float rounding, and the precomputed
// derivatives give the very same value.
TEST(GradientCorrelation, DirectSumsEqualOpenCvsNormalisedCrossCorrelation) {
  const cv::Mat drr = bone_drr(), xray = xray_of(drr);
  const XrayGradients x(xray, 1.0, false);
  for (const double shift : {0.0, 2.5, 8.0}) {
    const cv::Mat d = bone_drr(shift);
    const double direct = x.correlate(d);
    EXPECT_NEAR(direct, plain_correlation(xray, d), 2e-5) << "shift " << shift;
    EXPECT_EQ(direct, x.correlate(x.derivatives(d))) << "shift " << shift;
  }
}

// A DRR standing in for an X-ray from its derivatives (the confidence check's simulated X-ray)
// correlates bit for bit as the X-ray made from minus the DRR, with DRRs and with a noisy X-ray's
// derivatives alike, and a blank DRR stands in for a flat X-ray that correlates with nothing.
TEST(GradientCorrelation, ADrrAsXrayIsTheXrayOfMinusTheDrr) {
  const cv::Mat drr = bone_drr(), xray = xray_of(drr);
  const XrayGradients x(xray, 1.0);
  const XrayGradients::Derivatives d = x.derivatives(drr);
  const XrayGradients from_derivatives = x.drr_as_xray(d), made(-drr, 1.0, false);
  for (const double shift : {0.0, 1.5, 6.0}) {
    const cv::Mat other = bone_drr(shift);
    EXPECT_EQ(from_derivatives.correlate(other), made.correlate(other)) << "shift " << shift;
    EXPECT_GT(made.correlate(other), shift == 0.0 ? 0.999 : 0.0);
  }
  EXPECT_EQ(from_derivatives.correlate(x.derivatives(xray)), made.correlate(x.derivatives(xray)));
  const XrayGradients blank = x.drr_as_xray(x.derivatives(cv::Mat::zeros(drr.size(), CV_32F)));
  EXPECT_EQ(blank.correlate(drr), 0.0);
}

// A DRR with the bone out of view is blank: it must not score as a match (OpenCV's normalised
// cross-correlation calls a flat template a perfect one).
TEST(GradientCorrelation, ABlankDrrCorrelatesZero) {
  const cv::Mat drr = bone_drr();
  const XrayGradients x(xray_of(drr), 1.0);
  EXPECT_EQ(x.correlate(cv::Mat::zeros(drr.size(), CV_32F)), 0.0);
  EXPECT_EQ(x.correlate(cv::Mat(drr.size(), CV_32F, cv::Scalar(3.0))), 0.0);
}

}  // namespace
}  // namespace fluoro
