#pragma once
// A smooth global 2D map: each output coordinate a polynomial of total degree N in the input's
// normalised coordinates ((p - centre) / scale), fitted by linear least squares (Eigen QR).
#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace fluoro {

// Two polynomials (one per output coordinate) sharing a normalisation; copyable, immutable once fitted.
// Serialised in MAP.json (docs/calibration.md).
class PolynomialMap2 {
 public:
  PolynomialMap2() = default;
  // Least-squares fit of to[k] ~ map(from[k]); needs at least term_count(degree) points.
  static PolynomialMap2 fit(const std::vector<Eigen::Vector2d>& from, const std::vector<Eigen::Vector2d>& to,
                            int degree, const Eigen::Vector2d& centre, double scale);
  // Number of monomials x^a y^b with a + b <= degree.
  static int term_count(int degree) { return (degree + 1) * (degree + 2) / 2; }

  // The map at pixel p, and its total degree.
  Eigen::Vector2d operator()(const Eigen::Vector2d& p) const;
  int degree() const { return degree_; }

  // {"degree", "centre_px", "scale_px", "coefficients": [[cu, cv], ...]}, terms ordered by total
  // degree d = 0..N, then x^d, x^(d-1) y, ..., y^d.
  nlohmann::json to_json() const;
  // Throws InputError naming `what` on a malformed object.
  static PolynomialMap2 from_json(const nlohmann::json& j, const std::string& what);

 private:
  int degree_ = 0;
  Eigen::Vector2d centre_{0, 0};
  double scale_ = 1;
  Eigen::Matrix<double, Eigen::Dynamic, 2> coefficients_;
};

}  // namespace fluoro
