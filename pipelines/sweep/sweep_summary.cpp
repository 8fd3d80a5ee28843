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
}

// A number with `decimals` decimals, or nothing (CSV) / "-" (table) when undefined.
std::string number(double v, int decimals, const char* undefined) {
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
       "confident_among_successes_percent,mean_success_tre_mm\n";
  for (const SweepBinSummary& b : bins) {
    o << (std::isnan(b.distance_mm) ? std::string("all") : number(b.distance_mm, 6, "")) << ',' << b.runs << ','
      << b.successes << ',' << number(b.success_percent(), 2, "") << ',' << b.false_confident << ','
      << b.confident_successes << ',' << number(b.confident_among_successes_percent(), 2, "") << ','
      << number(b.mean_success_tre_mm(), 4, "") << '\n';
  }
  return o.str();
}

std::string sweep_summary_table(const std::vector<SweepBinSummary>& bins) {
  std::ostringstream o;
  o << "distance_mm  runs  success_%  false_confident  confident_of_successes_%  mean_TRE_of_successes_mm\n";
  for (const SweepBinSummary& b : bins) {
    char line[160];
    std::snprintf(line, sizeof line, "%11s %5d %10s %16d %25s %25s\n",
                  std::isnan(b.distance_mm) ? "all" : number(b.distance_mm, 1, "").c_str(), b.runs,
                  number(b.success_percent(), 1, "-").c_str(), b.false_confident,
                  number(b.confident_among_successes_percent(), 1, "-").c_str(),
                  number(b.mean_success_tre_mm(), 3, "-").c_str());
    o << line;
  }
  return o.str();
}

}  // namespace fluoro
