// fluoro pivot: pivot calibration of a tracked pointer from its poses (shared/docs/FORMATS.md).
#include <cmath>
#include <cstdio>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/global_options.hpp"
#include "apps/fluoro/provenance.hpp"
#include "apps/fluoro/result_files.hpp"
#include "engine/error.hpp"
#include "engine/json_io.hpp"
#include "engine/pose_list_io.hpp"
#include "pipelines/calibration/pivot_calibration.hpp"

namespace fluoro::cli {
namespace {

struct PivotOptions {
  std::string poses, out;
  double min_rotation_deg = PivotParams{}.min_rotation_spread_deg;
};

void run(const PivotOptions& o) {
  if (!std::isfinite(o.min_rotation_deg) || o.min_rotation_deg < 0)
    throw_input_error("--min-rotation-deg", "must be a non-negative number");
  StageTimer timer;
  const std::vector<Pose> poses = read_pose_list(o.poses);
  timer.lap("read");
  PivotParams params;
  params.min_rotation_spread_deg = o.min_rotation_deg;
  const PivotCalibration pivot = pivot_calibration(poses, params);
  timer.lap("solve");

  nlohmann::json doc;
  doc["status"] = pivot.ok ? "ok" : "failed";
  if (!pivot.ok) doc["reason"] = pivot.failure_reason;
  if (pivot.ok) {
    doc["tip_in_tool_mm"] = {pivot.tip_in_tool.x(), pivot.tip_in_tool.y(), pivot.tip_in_tool.z()};
    doc["pivot_in_tracker_mm"] = {pivot.pivot_in_tracker.x(), pivot.pivot_in_tracker.y(), pivot.pivot_in_tracker.z()};
    doc["rms_mm"] = pivot.rms_mm;
    doc["max_mm"] = pivot.max_mm;
  }
  doc["poses"] = pivot.poses;
  doc["rotation_spread_deg"] = pivot.rotation_spread_deg;
  doc["min_rotation_spread_deg"] = least_rotation_spread_deg(params);  // the limit applied (provenance: the option)
  doc["inputs"] = {{"poses", file_digest(o.poses)}};
  doc["provenance"] = provenance("pivot", {{"min_rotation_spread_deg", params.min_rotation_spread_deg}}, doc["inputs"]);
  doc["timings_s"] = timer.json();
  write_json(doc, o.out);
  if (!pivot.ok) throw MethodFailed(o.out + ": pivot calibration failed: " + pivot.failure_reason);
  if (!quiet())
    std::printf("%s: tip (%.3f, %.3f, %.3f) mm in the tool, pivot (%.3f, %.3f, %.3f) mm in the tracker, rms %.3f mm "
                "over %zu poses (rotation spread %.1f deg)\n",
                o.out.c_str(), pivot.tip_in_tool.x(), pivot.tip_in_tool.y(), pivot.tip_in_tool.z(),
                pivot.pivot_in_tracker.x(), pivot.pivot_in_tracker.y(), pivot.pivot_in_tracker.z(), pivot.rms_mm,
                pivot.poses, pivot.rotation_spread_deg);
}

}  // namespace

void add_pivot_command(CLI::App& app) {
  auto o = std::make_shared<PivotOptions>();
  auto* cmd = app.add_subcommand("pivot", "Pivot calibration: a tracked tool's tip from poses pivoting about it");
  cmd->add_option("--poses", o->poses, "POSES.json: {\"poses\": [T_tracker_tool 4x4, ...]}")->required();
  cmd->add_option("--out", o->out, "TIP.json: tip_in_tool_mm, pivot_in_tracker_mm, rms_mm")->required();
  cmd->add_option("--min-rotation-deg", o->min_rotation_deg,
                  "Fail unless the poses' rotation spread about two axes reaches this")
      ->capture_default_str();
  cmd->callback([o] { run(*o); });
}

}  // namespace fluoro::cli
