// Monomials in coordinates normalised to about [-1, 1] keep the degree-7 normal equations well
// conditioned enough for a QR solve in double precision.
#include "pipelines/calibration/polynomial_map.hpp"

#include <Eigen/QR>
#include <cmath>

#include "engine/error.hpp"

namespace fluoro {
namespace {

void monomials(const Eigen::Vector2d& n, int degree, double* out) {
  double xp[16], yp[16];
  xp[0] = yp[0] = 1;
  for (int k = 1; k <= degree; ++k) xp[k] = xp[k - 1] * n.x(), yp[k] = yp[k - 1] * n.y();
  int t = 0;
  for (int d = 0; d <= degree; ++d)
    for (int a = d; a >= 0; --a) out[t++] = xp[a] * yp[d - a];
}

}  // namespace

PolynomialMap2 PolynomialMap2::fit(const std::vector<Eigen::Vector2d>& from, const std::vector<Eigen::Vector2d>& to,
                                   int degree, const Eigen::Vector2d& centre, double scale) {
  PolynomialMap2 m;
  m.degree_ = degree, m.centre_ = centre, m.scale_ = scale;
  const int terms = term_count(degree);
  Eigen::MatrixXd M(Eigen::Index(from.size()), terms);
  Eigen::MatrixXd Y(Eigen::Index(from.size()), 2);
  std::vector<double> row(static_cast<size_t>(terms));
  for (size_t k = 0; k < from.size(); ++k) {
    monomials((from[k] - centre) / scale, degree, row.data());
    for (int t = 0; t < terms; ++t) M(Eigen::Index(k), t) = row[size_t(t)];
    Y.row(Eigen::Index(k)) = to[k].transpose();
  }
  m.coefficients_ = M.colPivHouseholderQr().solve(Y);
  return m;
}

Eigen::Vector2d PolynomialMap2::operator()(const Eigen::Vector2d& p) const {
  double row[136];
  monomials((p - centre_) / scale_, degree_, row);
  Eigen::Vector2d out(0, 0);
  for (Eigen::Index t = 0; t < coefficients_.rows(); ++t) out += row[t] * coefficients_.row(t).transpose();
  return out;
}

nlohmann::json PolynomialMap2::to_json() const {
  nlohmann::json c = nlohmann::json::array();
  for (Eigen::Index t = 0; t < coefficients_.rows(); ++t) c.push_back({coefficients_(t, 0), coefficients_(t, 1)});
  return {{"degree", degree_}, {"centre_px", {centre_.x(), centre_.y()}}, {"scale_px", scale_}, {"coefficients", c}};
}

PolynomialMap2 PolynomialMap2::from_json(const nlohmann::json& j, const std::string& what) {
  auto bad = [&](const std::string& problem) { throw_input_error(what, problem); };
  if (!j.is_object() || !j.contains("degree") || !j["degree"].is_number_integer()) bad("polynomial needs an integer \"degree\"");
  PolynomialMap2 m;
  m.degree_ = j["degree"].get<int>();
  if (m.degree_ < 1 || m.degree_ > 15) bad("polynomial degree must be 1 to 15");
  const auto& c = j.value("centre_px", nlohmann::json());
  if (!c.is_array() || c.size() != 2 || !c[0].is_number() || !c[1].is_number()) bad("polynomial \"centre_px\" must be [x, y]");
  m.centre_ = {c[0].get<double>(), c[1].get<double>()};
  if (!j.contains("scale_px") || !j["scale_px"].is_number() || !(j["scale_px"].get<double>() > 0)) bad("polynomial \"scale_px\" must be positive");
  m.scale_ = j["scale_px"].get<double>();
  const auto& k = j.value("coefficients", nlohmann::json());
  if (!k.is_array() || int(k.size()) != term_count(m.degree_))
    bad("polynomial of degree " + std::to_string(m.degree_) + " needs " + std::to_string(term_count(m.degree_)) + " coefficients");
  m.coefficients_.resize(Eigen::Index(k.size()), 2);
  for (size_t t = 0; t < k.size(); ++t) {
    if (!k[t].is_array() || k[t].size() != 2 || !k[t][0].is_number() || !k[t][1].is_number()) bad("polynomial coefficients must be [cu, cv] pairs");
    m.coefficients_(Eigen::Index(t), 0) = k[t][0].get<double>();
    m.coefficients_(Eigen::Index(t), 1) = k[t][1].get<double>();
  }
  if (!m.coefficients_.allFinite() || !m.centre_.allFinite()) bad("polynomial holds a non-finite number");
  return m;
}

}  // namespace fluoro
