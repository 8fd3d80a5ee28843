// fluoro icp: trimmed point-to-plane ICP of digitised points to a surface mesh or a CT's bone
// surface; the result is a pose file (shared/docs/FORMATS.md).
#include <cmath>
#include <cstdio>
#include <string>

#include "apps/fluoro/commands.hpp"
#include "apps/fluoro/global_options.hpp"
#include "apps/fluoro/provenance.hpp"
#include "apps/fluoro/result_files.hpp"
#include "engine/error.hpp"
#include "engine/json_io.hpp"
#include "engine/mesh_io.hpp"
#include "engine/point_list_io.hpp"
#include "engine/volume_io.hpp"
#include "kernels/mesh/closest_point.hpp"
#include "pipelines/calibration/ct_surface.hpp"
#include "pipelines/calibration/icp.hpp"

namespace fluoro::cli {
namespace {

struct IcpOptions {
  std::string points, mesh, ct, init, out;
  double iso_hu = 250.0, keep_fraction = IcpParams{}.keep_fraction, ct_voxel_mm = 1.0;
  int max_iterations = IcpParams{}.max_iterations;
};

void run(const IcpOptions& o) {
  if (!std::isfinite(o.iso_hu)) throw_input_error("--iso", "must be a number");
  if (!(o.keep_fraction > 0 && o.keep_fraction <= 1)) throw_input_error("--keep-fraction", "must be in (0, 1]");
  if (o.max_iterations < 1) throw_input_error("--max-iterations", "must be at least 1");
  if (!(o.ct_voxel_mm > 0) || !std::isfinite(o.ct_voxel_mm)) throw_input_error("--ct-voxel-mm", "must be a positive number");
  StageTimer timer;
  // Missing (null) points were not digitised: ICP needs no pairing, so they are simply left out.
  std::vector<Eigen::Vector3d> points;
  for (const auto& p : read_points_3d(o.points))
    if (p) points.push_back(*p);
  const Pose initial = read_pose(o.init);
  timer.lap("read");
  const TriangleMesh surface =
      o.mesh.empty() ? ct_bone_surface(read_volume(o.ct), o.iso_hu, o.ct_voxel_mm, o.ct) : read_mesh(o.mesh);
  const std::string model = o.mesh.empty() ? o.ct : o.mesh;
  timer.lap(o.mesh.empty() ? "surface" : "read_mesh");
  const MeshClosestPoint index(surface, model);
  timer.lap("index");
  IcpParams params;
  params.keep_fraction = o.keep_fraction;
  params.max_iterations = o.max_iterations;
  const IcpResult icp = icp_point_to_plane(index, points, initial, params);
  timer.lap("icp");

  nlohmann::json doc;
  doc["status"] = icp.ok ? "ok" : "failed";
  if (!icp.ok) doc["reason"] = icp.failure_reason;
  if (icp.ok) {
    doc["T_world_ct"] = pose_to_json(icp.T_world_model)["T_world_ct"];
    doc["rms_mm"] = icp.rms_mm;
    doc["inlier_fraction"] = icp.inlier_fraction;
  }
  doc["iterations"] = icp.iterations;
  doc["keep_fraction"] = params.keep_fraction;
  doc["points_used"] = points.size();
  doc["initial_T_world_ct"] = pose_to_json(initial)["T_world_ct"];
  doc["surface"] = {{"source", o.mesh.empty() ? "ct" : "mesh"}, {"triangles", index.triangle_count()}};
  if (o.mesh.empty()) doc["surface"]["iso_hu"] = o.iso_hu;
  nlohmann::json inputs = {{"points", file_digest(o.points)}, {"init", file_digest(o.init)}};
  inputs[o.mesh.empty() ? "ct" : "mesh"] = file_digest(model);
  doc["inputs"] = inputs;
  nlohmann::json settings = {{"surface", o.mesh.empty() ? "ct" : "mesh"},
                             {"keep_fraction", params.keep_fraction},
                             {"max_iterations", params.max_iterations},
                             {"min_rotation_step_deg", params.min_rotation_step_deg},
                             {"min_translation_step_mm", params.min_translation_step_mm}};
  if (o.mesh.empty()) settings["iso_hu"] = o.iso_hu, settings["ct_voxel_mm"] = o.ct_voxel_mm;
  doc["provenance"] = provenance("icp", settings, inputs);
  doc["timings_s"] = timer.json();
  write_json(doc, o.out);
  if (!icp.ok) throw MethodFailed(o.out + ": ICP failed: " + icp.failure_reason);
  if (!quiet())
    std::printf("%s: rms %.3f mm over the nearest %.0f%% of %zu points (%.1f%% within 3 rms), %d iterations, %.3f s\n",
                o.out.c_str(), icp.rms_mm, 100 * params.keep_fraction, points.size(), 100 * icp.inlier_fraction,
                icp.iterations, timer.total());
}

}  // namespace

void add_icp_command(CLI::App& app) {
  auto o = std::make_shared<IcpOptions>();
  auto* cmd = app.add_subcommand("icp", "Trimmed point-to-plane ICP of points to a surface mesh or a CT's bone surface");
  cmd->add_option("--points", o->points, "Point list (world frame)")->required();
  auto* mesh = cmd->add_option("--mesh", o->mesh, "Surface mesh (.stl, .ply, .obj), model frame");
  auto* ct = cmd->add_option("--ct", o->ct, "CT volume in HU; its surface at --iso is the model");
  mesh->excludes(ct);
  cmd->add_option("--iso", o->iso_hu, "Bone iso-value of the CT's surface, HU")->capture_default_str();
  cmd->add_option("--ct-voxel-mm", o->ct_voxel_mm, "The CT is box-averaged to about this spacing before meshing")
      ->capture_default_str();
  cmd->add_option("--init", o->init, "Initial pose file (T_world_ct: the model in the points' frame)")->required();
  cmd->add_option("--out", o->out, "Result pose file with rms_mm, iterations, inlier_fraction")->required();
  cmd->add_option("--keep-fraction", o->keep_fraction, "Fraction of point pairs kept, nearest first (trimming)")
      ->capture_default_str();
  cmd->add_option("--max-iterations", o->max_iterations, "Iterations before giving up")->capture_default_str();
  cmd->callback([o] {
    if (o->mesh.empty() && o->ct.empty()) throw_input_error("icp", "give --mesh MESH.stl|.ply|.obj or --ct CT");
    run(*o);
  });
}

}  // namespace fluoro::cli
