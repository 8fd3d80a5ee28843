// The sweep plot (seed, chapter 2, fig. 7) as a self-contained SVG: three panels sharing the
// initial-distance axis; the failure panel also shows, per bin, the false-confident runs (issue 14),
// and the seed's own failure rate where its text states one.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

#include "pipelines/sweep/sweep.hpp"

namespace fluoro {
namespace {

struct Bin {
  int runs = 0, failures = 0, successes = 0, false_confident = 0;
  double tre_sum = 0, seconds_sum = 0;
};

std::string fmt(double v, int decimals = 1) {
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  return b;
}

// A second series drawn in a panel: dashed, with square markers (class `marker_class`) and a legend.
struct SquareSeries {
  std::vector<std::pair<double, double>> points;
  std::string colour, marker_class, legend;
};

// A published point drawn for comparison: an open triangle (class `marker_class`) and a legend.
struct ReferencePoint {
  double x = 0, y = 0;
  std::string marker_class, legend;
};

// The seed's fig. 7 as its text gives it (Livyatan et al. 2003, section on the 4,250 runs of the
// dry femur): "A mean failure rate of 5% occurs at 72-mm", on the cumulative failure curve of
// panel (c). The figure's other points are not in the text, so only this one is drawn.
const ReferencePoint kSeedFigure7{72.0, 5.0, "seed-fig7",
                                  "the seed's fig. 7 (Livyatan et al.): 5 % cumulative failures at 72 mm"};

// One panel: a polyline of (x, y) with a marker at each point (a series of one point, say a sweep
// whose successes are all in one distance bin, has no line to draw), axes, ticks and a title.
void panel(std::ostringstream& svg, double top, const std::string& title, const std::string& colour,
           const std::vector<std::pair<double, double>>& points, double x_max, double y_max,
           const SquareSeries* squares = nullptr, const ReferencePoint* reference = nullptr) {
  const double left = 70, width = 620, height = 160;
  svg << "<g font-family='sans-serif' font-size='11'>\n";
  svg << "<text x='" << left << "' y='" << top - 8 << "' font-size='13'>" << title << "</text>\n";
  svg << "<rect x='" << left << "' y='" << top << "' width='" << width << "' height='" << height
      << "' fill='none' stroke='#444'/>\n";
  for (int i = 0; i <= 4; ++i) {
    const double y = top + height - height * i / 4.0;
    svg << "<line x1='" << left - 4 << "' y1='" << y << "' x2='" << left + width << "' y2='" << y
        << "' stroke='#ddd'/>\n<text x='" << left - 8 << "' y='" << y + 4 << "' text-anchor='end'>"
        << fmt(y_max * i / 4.0, y_max < 5 ? 2 : 1) << "</text>\n";
  }
  for (int i = 0; i <= 5; ++i) {
    const double x = left + width * i / 5.0;
    svg << "<text x='" << x << "' y='" << top + height + 14 << "' text-anchor='middle'>" << fmt(x_max * i / 5.0, 0)
        << "</text>\n";
  }
  const auto px = [&](double x) { return fmt(left + width * x / x_max, 2); };
  const auto py = [&](double y) { return fmt(top + height - height * std::min(y, y_max) / y_max, 2); };
  svg << "<polyline fill='none' stroke='" << colour << "' stroke-width='1.5' points='";
  for (const auto& [x, y] : points) svg << px(x) << ',' << py(y) << ' ';
  svg << "'/>\n";
  for (const auto& [x, y] : points)
    svg << "<circle cx='" << px(x) << "' cy='" << py(y) << "' r='2.5' fill='" << colour << "'/>\n";
  if (squares) {
    svg << "<polyline fill='none' stroke='" << squares->colour << "' stroke-width='1.2' stroke-dasharray='4 3' points='";
    for (const auto& [x, y] : squares->points) svg << px(x) << ',' << py(y) << ' ';
    svg << "'/>\n";
    for (const auto& [x, y] : squares->points)
      svg << "<rect class='" << squares->marker_class << "' x='" << fmt(left + width * x / x_max - 3, 2) << "' y='"
          << fmt(top + height - height * std::min(y, y_max) / y_max - 3, 2) << "' width='6' height='6' fill='"
          << squares->colour << "'/>\n";
    svg << "<rect x='" << left + 10 << "' y='" << top + 8 << "' width='6' height='6' fill='" << squares->colour
        << "'/>\n<text x='" << left + 22 << "' y='" << top + 14 << "'>" << squares->legend << "</text>\n";
  }
  // Only within the panel's distances (a sweep to 40 mm does not reach the seed's 72 mm).
  if (reference && reference->x <= x_max) {
    const auto triangle = [&](double cx, double cy) {
      return fmt(cx, 2) + "," + fmt(cy - 4, 2) + " " + fmt(cx - 4, 2) + "," + fmt(cy + 3, 2) + " " + fmt(cx + 4, 2) +
             "," + fmt(cy + 3, 2);
    };
    svg << "<polygon class='" << reference->marker_class << "' points='"
        << triangle(left + width * reference->x / x_max, top + height - height * std::min(reference->y, y_max) / y_max)
        << "' fill='none' stroke='#000' stroke-width='1.2'/>\n<polygon points='" << triangle(left + 13, top + 25)
        << "' fill='none' stroke='#000' stroke-width='1.2'/>\n<text x='" << left + 22 << "' y='" << top + 29 << "'>"
        << reference->legend << "</text>\n";
  }
  svg << "</g>\n";
}

}  // namespace

std::string sweep_plot_svg(const std::vector<SweepRow>& rows) {
  std::map<double, Bin> bins;
  for (const SweepRow& r : rows) {
    Bin& b = bins[r.run.distance_mm];
    ++b.runs;
    b.seconds_sum += r.seconds;
    if (r.success) {
      ++b.successes;
      b.tre_sum += r.final_tre_mm;
    } else {
      ++b.failures;
    }
    b.false_confident += r.final_tre_mm > 2.0 && r.confident;
  }
  std::vector<std::pair<double, double>> tre, failure, time;
  SquareSeries false_confident{{}, "#ff7f0e", "false-confident",
                               "false-confident runs (% of the bin's runs: final TRE > 2 mm, flagged confident)"};
  int runs = 0, failures = 0;
  double x_max = 1, tre_max = 0.5, time_max = 0.5;
  for (const auto& [d, b] : bins) {
    runs += b.runs;
    failures += b.failures;
    if (b.successes) tre.emplace_back(d, b.tre_sum / b.successes);
    failure.emplace_back(d, 100.0 * failures / runs);
    false_confident.points.emplace_back(d, 100.0 * b.false_confident / b.runs);
    time.emplace_back(d, b.seconds_sum / b.runs);
    x_max = std::max(x_max, d);
    if (b.successes) tre_max = std::max(tre_max, b.tre_sum / b.successes);
    time_max = std::max(time_max, b.seconds_sum / b.runs);
  }
  const auto nice = [](double v) { return std::ceil(v * 4.0) / 4.0 + (v > 4 ? std::ceil(v) - v : 0.0); };
  std::ostringstream svg;
  svg << "<svg xmlns='http://www.w3.org/2000/svg' width='720' height='690' viewBox='0 0 720 690'>\n"
      << "<rect width='100%' height='100%' fill='white'/>\n"
      << "<text x='70' y='22' font-family='sans-serif' font-size='15'>Registration sweep: " << rows.size()
      << " runs; x: initial surface TRE (mm)</text>\n";
  panel(svg, 60, "Final surface TRE of successful runs (mean, mm)", "#1f77b4", tre, x_max, nice(tre_max));
  panel(svg, 270, "Cumulative failures (% of runs up to this distance; failure: final TRE >= 2 mm)", "#d62728",
        failure, x_max, 100.0, &false_confident, &kSeedFigure7);
  panel(svg, 480, "Mean time per registration (s)", "#2ca02c", time, x_max, nice(time_max));
  svg << "</svg>\n";
  return svg.str();
}

}  // namespace fluoro
