#include "pipelines/sweep/sweep_summary.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <sstream>

namespace fluoro {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

void add(SweepBinSummary& b, const SweepRow& r) {
  ++b.runs;
  if (r.success) {
    ++b.successes;
    b.success_tre_sum_mm += r.final_tre_mm;
    b.confident_successes += r.confident;
  }
  // The criterion for the worst outcome: a wrong pose (over 2 mm) reported as right.
  if (r.final_tre_mm > 2.0 && r.confident) ++b.false_confident;
  // NaN (unmeasured) never wins: fmin/fmax return the other argument.
  const double sharpness = r.confidence.min_sharpness, offset = r.confidence.max_peak_offset;
  const double relative = r.confidence.relative_correlation;
  if (r.success) {
    b.least_success_sharpness = std::fmin(b.least_success_sharpness, sharpness);
    b.largest_success_peak_offset = std::fmax(b.largest_success_peak_offset, offset);
    b.least_success_relative_correlation = std::fmin(b.least_success_relative_correlation, relative);
  } else {
    b.greatest_failure_sharpness = std::fmax(b.greatest_failure_sharpness, sharpness);
    b.least_failure_peak_offset = std::fmin(b.least_failure_peak_offset, offset);
    b.greatest_failure_relative_correlation = std::fmax(b.greatest_failure_relative_correlation, relative);
  }
}

// A number with `decimals` decimals, "inf" or "-inf", or nothing (CSV) / "-" (table) when
// undefined (NaN).
std::string number(double v, int decimals, const char* undefined) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  if (!std::isfinite(v)) return undefined;
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  return b;
}

}  // namespace

double SweepBinSummary::confident_among_successes_percent() const {
  return successes ? 100.0 * confident_successes / successes : kNaN;
}

double SweepBinSummary::mean_success_tre_mm() const { return successes ? success_tre_sum_mm / successes : kNaN; }

std::vector<SweepBinSummary> summarize_sweep(const std::vector<SweepRow>& rows) {
  std::map<double, SweepBinSummary> bins;
  SweepBinSummary all;
  all.distance_mm = kNaN;
  for (const SweepRow& r : rows) {
    SweepBinSummary& b = bins[r.run.distance_mm];
    b.distance_mm = r.run.distance_mm;
    add(b, r);
    add(all, r);
  }
  std::vector<SweepBinSummary> out;
  for (const auto& [d, b] : bins) out.push_back(b);
  out.push_back(all);
  return out;
}

std::string sweep_summary_csv(const std::vector<SweepBinSummary>& bins) {
  std::ostringstream o;
  o << "distance_mm,runs,successes,success_percent,false_confident,confident_successes,"
       "confident_among_successes_percent,mean_success_tre_mm,least_success_sharpness,"
       "largest_success_peak_offset,greatest_failure_sharpness,least_failure_peak_offset,"
       "least_success_relative_correlation,greatest_failure_relative_correlation\n";
  for (const SweepBinSummary& b : bins) {
    o << (std::isnan(b.distance_mm) ? std::string("all") : number(b.distance_mm, 6, "")) << ',' << b.runs << ','
      << b.successes << ',' << number(b.success_percent(), 2, "") << ',' << b.false_confident << ','
      << b.confident_successes << ',' << number(b.confident_among_successes_percent(), 2, "") << ','
      << number(b.mean_success_tre_mm(), 4, "") << ',' << number(b.least_success_sharpness, 3, "") << ','
      << number(b.largest_success_peak_offset, 3, "") << ',' << number(b.greatest_failure_sharpness, 3, "") << ','
      << number(b.least_failure_peak_offset, 3, "") << ',' << number(b.least_success_relative_correlation, 3, "") << ','
      << number(b.greatest_failure_relative_correlation, 3, "") << '\n';
  }
  return o.str();
}

std::string sweep_summary_table(const std::vector<SweepBinSummary>& bins) {
  std::ostringstream o;
  // The last six: the margin of the confidence rule (sharpness >= 0.45, offset <= 0.4 mm or
  // degrees, every view's relative correlation >= 0.45), to three decimals like the thresholds
  // they are read against.
  o << "distance_mm  runs  success_%  false_confident  confident_of_successes_%  mean_TRE_of_successes_mm"
       "  successes:least_sharpness  largest_offset  least_relative  failures:greatest_sharpness  least_offset"
       "  greatest_relative\n";
  for (const SweepBinSummary& b : bins) {
    char line[320];
    std::snprintf(line, sizeof line, "%11s %5d %10s %16d %25s %25s %26s %15s %15s %28s %13s %18s\n",
                  std::isnan(b.distance_mm) ? "all" : number(b.distance_mm, 1, "").c_str(), b.runs,
                  number(b.success_percent(), 1, "-").c_str(), b.false_confident,
                  number(b.confident_among_successes_percent(), 1, "-").c_str(),
                  number(b.mean_success_tre_mm(), 3, "-").c_str(), number(b.least_success_sharpness, 3, "-").c_str(),
                  number(b.largest_success_peak_offset, 3, "-").c_str(),
                  number(b.least_success_relative_correlation, 3, "-").c_str(),
                  number(b.greatest_failure_sharpness, 3, "-").c_str(),
                  number(b.least_failure_peak_offset, 3, "-").c_str(),
                  number(b.greatest_failure_relative_correlation, 3, "-").c_str());
    o << line;
  }
  return o.str();
}

}  // namespace fluoro
