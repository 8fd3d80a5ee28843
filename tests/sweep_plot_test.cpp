// The sweep plot draws every series' points as markers, so a series of one point (a sweep whose
// successes all fall in one distance bin) is visible. Microseconds.
#include <gtest/gtest.h>

#include <string>

#include "pipelines/sweep/sweep.hpp"

namespace fluoro {
namespace {

SweepRow row(double distance_mm, bool success, double tre_mm) {
  SweepRow r;
  r.run.distance_mm = distance_mm;
  r.success = success;
  r.final_tre_mm = tre_mm;
  r.seconds = 1.5;
  return r;
}

// The markers between a panel's title and the next one's.
int markers_in_panel(const std::string& svg, const std::string& title, const std::string& next_title) {
  const size_t begin = svg.find(title), end = svg.find(next_title);
  EXPECT_NE(begin, std::string::npos);
  EXPECT_NE(end, std::string::npos);
  int n = 0;
  for (size_t at = svg.find("<circle", begin); at < end; at = svg.find("<circle", at + 1)) ++n;
  return n;
}

TEST(SweepPlot, ASeriesOfOnePointHasAMarker) {
  // Three distances; only the 5 mm bin has a success: the TRE series is one point.
  const std::string svg =
      sweep_plot_svg({row(5, true, 0.8), row(5, false, 9), row(10, false, 12), row(15, false, 20)});
  EXPECT_EQ(markers_in_panel(svg, "Final surface TRE", "Cumulative failures"), 1);
  EXPECT_EQ(markers_in_panel(svg, "Cumulative failures", "Mean time per registration"), 3);
  EXPECT_EQ(markers_in_panel(svg, "Mean time per registration", "</svg>"), 3);
  // The marker sits where the point is: x = 5 of 15 mm across the 620-pixel panel from x = 70.
  EXPECT_NE(svg.find("<circle cx='276.67'"), std::string::npos) << svg;
}

// The seed's published point (5 % cumulative failures at 72 mm) is drawn on the failure panel,
// where a sweep's distances reach it: at x = 72 of 85 mm, y = 5 % of the 160-px panel from 270.
TEST(SweepPlot, TheSeedsFailureRateIsDrawnBesideOurs) {
  const std::string far = sweep_plot_svg({row(10, true, 0.3), row(85, false, 9)});
  const size_t at = far.find("<polygon class='seed-fig7' points='595.18,418.00 ");
  EXPECT_NE(at, std::string::npos) << far;
  EXPECT_GT(at, far.find("Cumulative failures"));
  EXPECT_LT(at, far.find("Mean time per registration"));
  EXPECT_NE(far.find("5 % cumulative failures at 72 mm"), std::string::npos);
  const std::string near = sweep_plot_svg({row(10, true, 0.3), row(40, false, 9)});
  EXPECT_EQ(near.find("seed-fig7"), std::string::npos) << near;
}

}  // namespace
}  // namespace fluoro
