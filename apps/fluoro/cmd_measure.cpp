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
#include "engine/json_io.hpp"

namespace fluoro::cli {
namespace {

struct MeasureOptions {
  std::string report, points, out;
};

double number_at(const nlohmann::json& j, const std::string& key, const std::string& path) {
  if (!j.contains(key) || !j[key].is_number() || !std::isfinite(j[key].get<double>()))
    throw_input_error(path, "\"" + key + "\" must be a number");
  return j[key].get<double>();
}

void run(const MeasureOptions& o) {
  StageTimer timer;
  const nlohmann::json pano = read_json(o.report);
  if (!pano.is_object()) throw_input_error(o.report, "not a panorama report (a JSON object)");
  if (pano.value("status", std::string()) != "ok")
    throw_input_error(o.report, "the panorama failed (status is not \"ok\"): there is nothing to measure on");
  const double mm = number_at(pano, "mm_per_pixel", o.report);
  if (!(mm > 0)) throw_input_error(o.report, "\"mm_per_pixel\" must be positive");
  if (!pano.contains("size") || !pano["size"].is_array() || pano["size"].size() != 2 || !pano["size"][0].is_number() ||
      !pano["size"][1].is_number())
    throw_input_error(o.report, "\"size\" must be [width, height]");
  const double w = pano["size"][0].get<double>(), h = pano["size"][1].get<double>();
  double q[4];
  char c[3] = {0, 0, 0};
  std::istringstream in(o.points);
  if (!(in >> q[0] >> c[0] >> q[1] >> c[1] >> q[2] >> c[2] >> q[3]) || c[0] != ',' || c[1] != ',' || c[2] != ',' ||
      !(in >> std::ws).eof())
    throw_input_error("--points " + o.points, "expected u1,v1,u2,v2");
  for (int k = 0; k < 4; ++k)
    if (!std::isfinite(q[k]) || q[k] < -0.5 || q[k] > (k % 2 ? h : w) - 0.5)
      throw_input_error("--points " + o.points, "a point lies outside the " + std::to_string(int(w)) + " x " +
                                                    std::to_string(int(h)) + " panorama");
  const double px = std::hypot(q[2] - q[0], q[3] - q[1]);
  const double d = px * mm;
  // Uncertainty: the scale's relative error over the whole distance, plus each end's placement
  // error (a frame's position along the ruler, or the adjustment's residual) in quadrature.
  double rel = 0, pos = 0;
  if (pano.contains("uncertainty") && pano["uncertainty"].is_object()) {
    rel = pano["uncertainty"].value("scale_relative", 0.0);
    pos = pano["uncertainty"].value("position_px", 0.0);
  }
  const double u = std::sqrt(std::pow(d * rel, 2) + 2 * std::pow(pos * mm, 2));
  std::printf("distance_mm: %.6g\n", d);
  if (!o.out.empty()) {
    nlohmann::json m;
    m["status"] = "ok";
    m["distance_mm"] = d;
    m["uncertainty_mm"] = u;
    m["distance_px"] = px;
    m["plane"] = pano.value("plane", std::string("ruler"));
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
