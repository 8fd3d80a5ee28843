// fluoro measure: a distance on a panorama, in millimetres in its plane, with its uncertainty
// (shared/docs/FORMATS.md "Panorama").
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/global_options.hpp"
#include "apps/fluoro/provenance.hpp"
#include "apps/fluoro/result_files.hpp"
#include "engine/error.hpp"
#include "pipelines/panorama/panorama_document.hpp"
#include "engine/json_io.hpp"

namespace fluoro::cli {
namespace {

struct MeasureOptions {
  std::string report, points, out;
};

void run(const MeasureOptions& o) {
  if (!o.out.empty()) check_output_path(o.out);  // before anything is printed
  StageTimer timer;
  const nlohmann::json pano = read_json(o.report);
  check_panorama_report(pano, o.report);  // the report's problems before the points'
  double q[4];
  char c[3] = {0, 0, 0};
  std::istringstream in(o.points);
  if (!(in >> q[0] >> c[0] >> q[1] >> c[1] >> q[2] >> c[2] >> q[3]) || c[0] != ',' || c[1] != ',' || c[2] != ',' ||
      !(in >> std::ws).eof())
    throw_input_error("--points " + o.points, "expected u1,v1,u2,v2");
  const PanoramaDistance r = measure_on_panorama(pano, o.report, {q[0], q[1]}, {q[2], q[3]}, "--points " + o.points);
  const double d = r.distance_mm, px = r.distance_px;
  std::printf("distance_mm: %.6g\n", d);
  if (!r.uncertainty_mm)
    std::printf("uncertainty_mm: unknown (%s has no \"uncertainty\" section)\n", o.report.c_str());
  if (!o.out.empty()) {
    nlohmann::json m;
    m["status"] = "ok";
    m["distance_mm"] = d;
    m["uncertainty_mm"] = r.uncertainty_mm ? nlohmann::json(*r.uncertainty_mm) : nlohmann::json(nullptr);
    m["distance_px"] = px;
    // FORMATS.md's PANO.json always says its plane (checked above when there); a report without
    // one gets null, not a guess.
    m["plane"] = pano.contains("plane") ? pano["plane"] : nlohmann::json(nullptr);
    m["points"] = {{q[0], q[1]}, {q[2], q[3]}};
    m["inputs"] = nlohmann::json::array({file_digest(o.report)});
    m["provenance"] = provenance("measure", {{"points_px", m["points"]}}, m["inputs"]);
    timer.lap("measure");
    m["timings_s"] = timer.json();
    write_json(m, o.out);
  }
}

}  // namespace

void add_measure_command(CLI::App& app) {
  auto o = std::make_shared<MeasureOptions>();
  auto* cmd = app.add_subcommand("measure", "Distance in mm between two panorama pixels, in the panorama's plane");
  cmd->add_option("--report", o->report, "PANO.json written by fluoro panorama")->required();
  cmd->add_option("--points", o->points, "u1,v1,u2,v2 (panorama pixels)")->required();
  cmd->add_option("--out", o->out, "M.json: distance_mm, uncertainty_mm");
  cmd->callback([o] { run(*o); });
}

}  // namespace fluoro::cli
