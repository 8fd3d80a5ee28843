#pragma once
// Per-distance-bin summary of a sweep's runs (issue 14): how often the registration succeeds from
// each initial distance, and whether its confidence flag can be trusted there. Computed from the
// rows alone, so an existing RUNS.csv is summarised without re-running it.
#include <limits>
#include <string>
#include <vector>

#include "pipelines/sweep/sweep.hpp"

namespace fluoro {

struct SweepBinSummary {
  static constexpr double kUnmeasured = std::numeric_limits<double>::quiet_NaN();
  double distance_mm = 0;        // the bin: the requested initial surface TRE
  int runs = 0;
  int successes = 0;             // SweepRow::success (ok and final mean surface TRE < 2 mm)
  int false_confident = 0;       // final mean surface TRE > 2 mm, yet flagged confident
  int confident_successes = 0;   // successes flagged confident
  double success_tre_sum_mm = 0; // over the successes
  // The confidence rule's margin (the peak-sharpness test at the result, docs/registration.md,
  // "Confidence"; a result is confident only with sharpness >= 0.45 and peak offset <= 0.4 mm or
  // degrees in every view, and every view's relative correlation at least its floor, below): how
  // close the successes came to being refused and the failures to being trusted, each bound over
  // the bin's runs (not necessarily one run's). Over the runs that
  // measured them (NaN when none did; runs files written before these columns existed have
  // none). The offset is +inf when a view had no peak.
  double least_success_sharpness = kUnmeasured;
  double largest_success_peak_offset = kUnmeasured;
  double greatest_failure_sharpness = kUnmeasured;
  double least_failure_peak_offset = kUnmeasured;
  // The same for the relative correlation floor (RegistrationOptions::min_relative_correlation,
  // 0.45: every view's correlation over what a right pose would score there): the successes'
  // least and the failures' greatest least-view ratio.
  double least_success_relative_correlation = kUnmeasured;
  double greatest_failure_relative_correlation = kUnmeasured;

  double success_percent() const { return runs ? 100.0 * successes / runs : 0.0; }
  // Undefined (NaN) without a success.
  double confident_among_successes_percent() const;
  double mean_success_tre_mm() const;
};

// One entry per distance bin, by increasing distance, then (last) the whole sweep with
// distance_mm NaN.
std::vector<SweepBinSummary> summarize_sweep(const std::vector<SweepRow>& rows);

// SUMMARY.csv (docs/cli.md): a header, one line per bin, and a last line "all" for the whole
// sweep; a quantity undefined for a bin (no success, nothing measured) is an empty field, an
// infinite peak offset "inf".
std::string sweep_summary_csv(const std::vector<SweepBinSummary>& bins);

// The same as an aligned text table for the terminal.
std::string sweep_summary_table(const std::vector<SweepBinSummary>& bins);

}  // namespace fluoro
