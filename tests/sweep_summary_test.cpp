// The per-distance summary of a sweep (issue 14): counts of a crafted set of runs with known
// successes, false-confident runs and confident successes, in the summary CSV, the printed table,
// `fluoro sweep --summarize` on an existing runs file and the plot's false-confident markers.
// Milliseconds (no registration runs).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "pipelines/sweep/sweep_summary.hpp"
#include "tests/cli_fixture.hpp"

namespace fluoro {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// sharpness, peak_offset: the peak-sharpness test at the result; relative: the least view's
// relative correlation there (NaN: not measured).
SweepRow row(int index, double distance_mm, double final_tre_mm, bool confident, double sharpness = kNaN,
             double peak_offset = kNaN, double relative = kNaN) {
  SweepRow r;
  r.confidence.min_sharpness = sharpness;
  r.confidence.max_peak_offset = peak_offset;
  r.confidence.relative_correlation = relative;
  r.run.index = index;
  r.run.distance_mm = distance_mm;
  r.run.seed = 100 + uint64_t(index);
  r.final_tre_mm = final_tre_mm;
  r.ok = true;
  r.success = final_tre_mm < 2.0;
  r.confident = confident;
  r.seconds = 1.0;
  return r;
}

// 10 mm: 4 runs, 3 successes (0.2, 0.4, 0.6 mm; two confident), one failure flagged doubtful.
// 40 mm: 3 runs, 1 success (1.0 mm, confident), two failures of which one is flagged confident.
// 85 mm: 2 runs, no success, both failures flagged confident.
// Peak sharpness and offset where measured: the margin is the least sharpness and the largest
// offset of the successes (10 mm: 0.40 and a view without a peak), the greatest sharpness and the
// least offset of the failures (40 mm: 0.50 and 0.20); unmeasured runs (the 40 mm success first in
// its bin, a 40 and an 85 mm failure last in theirs) count for nothing. The relative correlation
// likewise: the successes' least (10 mm: 0.50), the failures' greatest (85 mm: 0.70).
std::vector<SweepRow> crafted_rows() {
  return {row(0, 10, 0.2, true, 0.80, 0.10, 0.95),  row(1, 10, 0.4, true, 0.60, 0.30, 0.90),
          row(2, 10, 0.6, false, 0.40, kInf, 0.50), row(3, 10, 14.0, false, 0.10, 1.5, 0.30),
          row(4, 40, 1.0, true),                    row(5, 40, 1.2, true, 0.70, 0.35, 0.85),
          row(6, 40, 9.0, true, 0.50, 0.20, 0.60),  row(7, 40, 30.0, false),
          row(8, 85, 22.7, true, 0.46, 0.39, 0.70), row(9, 85, 40.0, true)};
}

TEST(SweepSummary, CountsPerDistanceBin) {
  const std::vector<SweepBinSummary> bins = summarize_sweep(crafted_rows());
  ASSERT_EQ(bins.size(), 4u);  // three bins and the whole sweep
  EXPECT_EQ(bins[0].distance_mm, 10);
  EXPECT_EQ(bins[0].runs, 4);
  EXPECT_EQ(bins[0].successes, 3);
  EXPECT_EQ(bins[0].false_confident, 0);
  EXPECT_EQ(bins[0].confident_successes, 2);
  EXPECT_DOUBLE_EQ(bins[0].success_percent(), 75.0);
  EXPECT_NEAR(bins[0].confident_among_successes_percent(), 200.0 / 3.0, 1e-12);
  EXPECT_NEAR(bins[0].mean_success_tre_mm(), 0.4, 1e-12);

  EXPECT_EQ(bins[1].distance_mm, 40);
  EXPECT_EQ(bins[1].successes, 2);
  EXPECT_EQ(bins[1].false_confident, 1);
  EXPECT_DOUBLE_EQ(bins[1].confident_among_successes_percent(), 100.0);

  EXPECT_EQ(bins[2].distance_mm, 85);
  EXPECT_EQ(bins[2].successes, 0);
  EXPECT_EQ(bins[2].false_confident, 2);
  EXPECT_TRUE(std::isnan(bins[2].confident_among_successes_percent()));
  EXPECT_TRUE(std::isnan(bins[2].mean_success_tre_mm()));

  // The margin: successes' least sharpness and largest offset, failures' greatest sharpness and
  // least offset, and the successes' least and failures' greatest relative correlation (NaN: no
  // run of the kind measured them).
  auto expect_margin = [](const SweepBinSummary& b, double least, double largest, double greatest, double least_failure,
                          double least_relative, double greatest_relative) {
    auto same = [](double got, double want) { return std::isnan(want) ? std::isnan(got) : got == want; };
    EXPECT_TRUE(same(b.least_success_sharpness, least)) << b.distance_mm << ": " << b.least_success_sharpness;
    EXPECT_TRUE(same(b.largest_success_peak_offset, largest)) << b.distance_mm << ": " << b.largest_success_peak_offset;
    EXPECT_TRUE(same(b.greatest_failure_sharpness, greatest)) << b.distance_mm << ": " << b.greatest_failure_sharpness;
    EXPECT_TRUE(same(b.least_failure_peak_offset, least_failure)) << b.distance_mm << ": " << b.least_failure_peak_offset;
    EXPECT_TRUE(same(b.least_success_relative_correlation, least_relative)) << b.distance_mm;
    EXPECT_TRUE(same(b.greatest_failure_relative_correlation, greatest_relative)) << b.distance_mm;
  };
  expect_margin(bins[0], 0.40, kInf, 0.10, 1.5, 0.50, 0.30);
  expect_margin(bins[1], 0.70, 0.35, 0.50, 0.20, 0.85, 0.60);
  expect_margin(bins[2], kNaN, kNaN, 0.46, 0.39, kNaN, 0.70);
  expect_margin(bins[3], 0.40, kInf, 0.50, 0.20, 0.50, 0.70);

  EXPECT_TRUE(std::isnan(bins[3].distance_mm));
  EXPECT_EQ(bins[3].runs, 10);
  EXPECT_EQ(bins[3].successes, 5);
  EXPECT_EQ(bins[3].false_confident, 3);
  EXPECT_EQ(bins[3].confident_successes, 4);
  EXPECT_NEAR(bins[3].mean_success_tre_mm(), 0.68, 1e-12);
}

TEST(SweepSummary, CsvHasOneLinePerBinAndTheTotal) {
  const std::string csv = sweep_summary_csv(summarize_sweep(crafted_rows()));
  EXPECT_EQ(csv,
            "distance_mm,runs,successes,success_percent,false_confident,confident_successes,"
            "confident_among_successes_percent,mean_success_tre_mm,least_success_sharpness,"
            "largest_success_peak_offset,greatest_failure_sharpness,least_failure_peak_offset,"
            "least_success_relative_correlation,greatest_failure_relative_correlation\n"
            "10.000000,4,3,75.00,0,2,66.67,0.4000,0.400,inf,0.100,1.500,0.500,0.300\n"
            "40.000000,4,2,50.00,1,2,100.00,1.1000,0.700,0.350,0.500,0.200,0.850,0.600\n"
            "85.000000,2,0,0.00,2,0,,,,,0.460,0.390,,0.700\n"
            "all,10,5,50.00,3,4,80.00,0.6800,0.400,inf,0.500,0.200,0.500,0.700\n");
}

TEST(SweepSummary, PlotMarksTheFalseConfidentRunsOfEachBin) {
  const std::string svg = sweep_plot_svg(crafted_rows());
  // One square per bin, at the bin's false-confident percentage: 0, 25 and 100 % at 10, 40 and 85 mm of 85 on the 160-px
  // tall panel whose top is at y = 270 (markers are 6 px squares centred on the point).
  EXPECT_NE(svg.find("<rect class='false-confident' x='139.94' y='427.00'"), std::string::npos) << svg;
  EXPECT_NE(svg.find("<rect class='false-confident' x='358.76' y='387.00'"), std::string::npos) << svg;
  EXPECT_NE(svg.find("<rect class='false-confident' x='687.00' y='267.00'"), std::string::npos) << svg;
  int squares = 0;
  for (size_t at = svg.find("class='false-confident'"); at != std::string::npos;
       at = svg.find("class='false-confident'", at + 1))
    ++squares;
  EXPECT_EQ(squares, 3);
}

using test::CliResult;
class SweepSummaryCli : public test::CliTest {
 protected:
  void write_runs(const std::string& name) const {
    std::string text = sweep_csv_header() + "\n";
    for (const SweepRow& r : crafted_rows()) text += sweep_csv_row(r) + "\n";
    write_text(name, text);
  }
};

TEST_F(SweepSummaryCli, SummarisesAnExistingRunsFile) {
  write_runs("runs.csv");
  const CliResult r = run("sweep --summarize " + path("runs.csv") + " --plot " + path("plot.svg"));
  ASSERT_EQ(r.code, 0) << r.err;
  // Beside the runs file by default.
  const std::string csv = slurp(path("runs_summary.csv"));
  // The sharpness and relative columns read back, "nan" (unmeasured) and "inf" (no peak) included.
  EXPECT_NE(csv.find("\n40.000000,4,2,50.00,1,2,100.00,1.1000,0.700,0.350,0.500,0.200,0.850,0.600\n"), std::string::npos) << csv;
  EXPECT_NE(csv.find("\n85.000000,2,0,0.00,2,0,,,,,0.460,0.390,,0.700\n"), std::string::npos) << csv;
  EXPECT_NE(csv.find("\nall,10,5,50.00,3,4,80.00,0.6800,0.400,inf,0.500,0.200,0.500,0.700\n"), std::string::npos) << csv;
  EXPECT_NE(slurp(path("plot.svg")).find("class='false-confident'"), std::string::npos);
  EXPECT_NE(r.out.find("10 runs"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("false_confident"), std::string::npos) << r.out;
  // The whole line, the margin to three decimals under its column headers.
  EXPECT_NE(r.out.find("\n        all    10       50.0                3                      80.0                     0.680                      0.400             inf           0.500                        0.500         0.200              0.700\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("failures:greatest_sharpness  least_offset  greatest_relative\n"), std::string::npos) << r.out;
  // Or where --summary says.
  ASSERT_EQ(run("sweep --summarize " + path("runs.csv") + " --summary " + path("s.csv")).code, 0);
  EXPECT_EQ(slurp(path("s.csv")), csv);
}

TEST_F(SweepSummaryCli, ReadsRunsFilesOfTheFormerHeaderWithoutTheirMargin) {
  // Written before the min_sharpness and max_peak_offset columns: the counts as ever, the
  // margin fields empty.
  std::string text =
      "run,distance_mm,seed,initial_tre_mm,final_tre_mm,final_tre_max_mm,fiducial_tre_mm,mpd_mm,rotation_deg,"
      "translation_mm,success,ok,confident,gradient_correlation,seconds,coarse_seconds,fine_seconds,evaluations,"
      "min_view_correlation\n";
  for (const SweepRow& r : crafted_rows()) {
    std::string line = sweep_csv_row(r);
    for (int cut = 0; cut < 3; ++cut) line.resize(line.rfind(','));
    text += line + "\n";
  }
  write_text("old.csv", text);
  const CliResult r = run("sweep --summarize " + path("old.csv"));
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string csv = slurp(path("old_summary.csv"));
  EXPECT_NE(csv.find("\n40.000000,4,2,50.00,1,2,100.00,1.1000,,,,,,\n"), std::string::npos) << csv;
  EXPECT_NE(csv.find("\nall,10,5,50.00,3,4,80.00,0.6800,,,,,,\n"), std::string::npos) << csv;
}

TEST_F(SweepSummaryCli, ReadsRunsFilesOfTheSharpnessHeaderWithoutTheirRelativeCorrelation) {
  // Written 2026-12-03 to 04, before the relative_correlation column: the sharpness margin as
  // ever, the relative one empty.
  std::string text =
      "run,distance_mm,seed,initial_tre_mm,final_tre_mm,final_tre_max_mm,fiducial_tre_mm,mpd_mm,rotation_deg,"
      "translation_mm,success,ok,confident,gradient_correlation,seconds,coarse_seconds,fine_seconds,evaluations,"
      "min_view_correlation,min_sharpness,max_peak_offset\n";
  for (const SweepRow& r : crafted_rows()) {
    std::string line = sweep_csv_row(r);
    line.resize(line.rfind(','));
    text += line + "\n";
  }
  write_text("sharp.csv", text);
  const CliResult r = run("sweep --summarize " + path("sharp.csv"));
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string csv = slurp(path("sharp_summary.csv"));
  EXPECT_NE(csv.find("\n40.000000,4,2,50.00,1,2,100.00,1.1000,0.700,0.350,0.500,0.200,,\n"), std::string::npos) << csv;
  EXPECT_NE(csv.find("\nall,10,5,50.00,3,4,80.00,0.6800,0.400,inf,0.500,0.200,,\n"), std::string::npos) << csv;
}

TEST_F(SweepSummaryCli, RefusesWhatItCannotSummarise) {
  expect_bad_input(run("sweep --summarize " + path("absent.csv")), "absent.csv: no such runs file");
  write_text("other.csv", "a,b,c\n1,2,3\n");
  expect_bad_input(run("sweep --summarize " + path("other.csv")), "other.csv: not a sweep CSV", "other_summary.csv");
  write_runs("runs.csv");
  expect_bad_input(run("sweep --summarize " + path("runs.csv") + " --out " + path("x.csv")), "--summarize");
  expect_bad_input(run("sweep --summarize " + path("runs.csv") + " --summary " + path("runs.csv")),
                   "runs.csv: is the runs file itself");
  expect_bad_input(run("sweep --out " + path("x.csv")), "needs --config");
}

}  // namespace
}  // namespace fluoro
