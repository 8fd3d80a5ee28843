// fluoro pivot, register-points and icp end to end: the result files' keys (shared/docs/FORMATS.md)
// and values against the generated truth, exit 2 with one line and no output on bad input, exit 3
// with a "failed" result file on readable input that defeats the method.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "datasets/point_tool_scenes.hpp"
#include "pipelines/calibration/pivot_calibration.hpp"
#include "tests/cli_fixture.hpp"
#include "engine/json_io.hpp"
#include "engine/point_list_io.hpp"
#include "engine/volume_io.hpp"
#include "pipelines/registration/bone_mesh.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::CliResult;

class PointToolsCli : public test::CliTest {
 protected:
  void write_poses(const std::string& name, const std::vector<Pose>& poses) const {
    json list = json::array();
    for (const Pose& p : poses) list.push_back(pose_to_json(p)["T_world_ct"]);
    write_json(json{{"poses", list}}, path(name));
  }
  void write_points(const std::string& name, const std::vector<Eigen::Vector3d>& points) const {
    PointList3 list(points.begin(), points.end());
    write_points_3d(list, path(name));
  }
  void write_binary_stl(const std::string& name, const TriangleMesh& mesh) const {
    std::ofstream f(path(name), std::ios::binary);
    f << std::string(80, ' ');
    const uint32_t n = uint32_t(mesh.triangles.size());
    f.write(reinterpret_cast<const char*>(&n), 4);
    for (const auto& t : mesh.triangles) {
      float record[12] = {};
      for (int k = 0; k < 3; ++k)
        for (int i = 0; i < 3; ++i) record[3 + 3 * k + i] = float(mesh.vertices[size_t(t[size_t(k)])][i]);
      f.write(reinterpret_cast<const char*>(record), sizeof record);
      f.write("\0\0", 2);
    }
  }
  static Eigen::Vector3d vec(const json& j) { return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()}; }
  static Pose pose(const json& j) {
    Eigen::Matrix4d m;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) m(r, c) = j[size_t(r)][size_t(c)].get<double>();
    return pose_from_matrix(m, "result");
  }
};

TEST_F(PointToolsCli, PivotWritesTipPivotAndRms) {
  const Eigen::Vector3d tip(-2, 4, 160), pivot(-50, 120, -900);
  write_poses("poses.json", make_pivot_poses(tip, pivot, 60, 25, 0.1, 9));
  const CliResult r = run("pivot --poses " + path("poses.json") + " --out " + path("tip.json"));
  ASSERT_EQ(r.code, 0) << r.err;
  const json doc = read_json(path("tip.json"));
  EXPECT_EQ(doc["status"], "ok");
  EXPECT_LT((vec(doc["tip_in_tool_mm"]) - tip).norm(), 0.3);
  EXPECT_LT((vec(doc["pivot_in_tracker_mm"]) - pivot).norm(), 0.3);
  EXPECT_NEAR(doc["rms_mm"].get<double>(), 0.1 * std::sqrt(3.0), 0.05);
  EXPECT_TRUE(doc["inputs"]["poses"]["bytes"].get<double>() > 0);
  EXPECT_TRUE(doc["timings_s"].is_object());
  expect_provenance(doc, "pivot");
  EXPECT_EQ(doc["provenance"]["settings"]["min_rotation_spread_deg"], doc["min_rotation_spread_deg"]);
}

TEST_F(PointToolsCli, PivotBadInputAndDegeneratePoses) {
  write_text("nan.json", "{\"poses\": [[[1,0,0,NaN],[0,1,0,0],[0,0,1,0],[0,0,0,1]]]}");
  expect_bad_input(run("pivot --poses " + path("nan.json") + " --out " + path("tip.json")), "nan.json", "tip.json");
  write_text("shear.json", "{\"poses\": [[[1,0.5,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]]}");
  expect_bad_input(run("pivot --poses " + path("shear.json") + " --out " + path("tip.json")), "shear.json: pose 0",
                   "tip.json");
  write_poses("two.json", make_pivot_poses({0, 0, 100}, {0, 0, 0}, 2, 30, 0, 1));
  expect_failed(run("pivot --poses " + path("two.json") + " --out " + path("tip.json")), "tip.json",
                {"tip_in_tool_mm", "pivot_in_tracker_mm", "rms_mm"});
  // Pivoting about one axis only: the tip's component along it is free.
  std::vector<Pose> one_axis;
  for (int i = 0; i < 12; ++i) {
    Pose T = pose_from_rotation_vector(Eigen::Vector3d(0, 0.05 * i, 0), Eigen::Vector3d::Zero());
    T.translation() = -(T.linear() * Eigen::Vector3d(0, 0, 100));
    one_axis.push_back(T);
  }
  write_poses("one_axis.json", one_axis);
  const json doc = expect_failed(run("pivot --poses " + path("one_axis.json") + " --out " + path("tip2.json")),
                                 "tip2.json", {"tip_in_tool_mm"});
  EXPECT_NE(doc["reason"].get<std::string>().find("rotate too little"), std::string::npos);
  // Even with the spread's limit turned off, one-axis pivoting is a failure, not a tip of NaN.
  const json off = expect_failed(run("pivot --poses " + path("one_axis.json") + " --out " + path("tip3.json") +
                                     " --min-rotation-deg 0"),
                                 "tip3.json", {"tip_in_tool_mm"});
  EXPECT_NE(off["reason"].get<std::string>().find("rotate too little"), std::string::npos);
  EXPECT_EQ(off["min_rotation_spread_deg"].get<double>(), kUndeterminedRotationSpreadDeg);  // the limit applied
}

TEST_F(PointToolsCli, RegisterPointsWithTargetsAndEstimatedFle) {
  const std::vector<Eigen::Vector3d> moving = {{0, 0, 0}, {80, 10, 5}, {20, 90, -10}, {-30, 40, 60}, {60, 70, 40}};
  const Pose truth = pose_from_rotation_vector(Eigen::Vector3d(0.3, -0.2, 0.9), Eigen::Vector3d(10, 20, 30));
  std::vector<Eigen::Vector3d> fixed;
  const Eigen::Vector3d wobble[5] = {{0.2, 0, 0}, {0, -0.2, 0}, {0, 0, 0.2}, {-0.2, 0.1, 0}, {0, 0.1, -0.2}};
  for (size_t i = 0; i < moving.size(); ++i) fixed.push_back(truth * moving[i] + wobble[i]);
  write_points("fixed.json", fixed);
  write_points("moving.json", moving);
  write_points("targets.json", {{30, 40, 20}, {200, 0, 0}});
  const CliResult r = run("register-points --fixed " + path("fixed.json") + " --moving " + path("moving.json") +
                          " --targets " + path("targets.json") + " --out " + path("r.json"));
  ASSERT_EQ(r.code, 0) << r.err;
  const json doc = read_json(path("r.json"));
  EXPECT_EQ(doc["status"], "ok");
  expect_provenance(doc, "register-points");
  const Pose T = pose(doc["T_fixed_moving"]);
  EXPECT_LT((T * moving[0] - truth * moving[0]).norm(), 0.5);
  const double fre = doc["fre_rms_mm"].get<double>();
  EXPECT_GT(fre, 0.05);
  EXPECT_LT(fre, 0.3);
  ASSERT_EQ(doc["predicted_tre_rms_mm"].size(), 2u);
  EXPECT_NEAR(doc["fle_rms_mm"].get<double>(), fre * std::sqrt(5.0 / 3.0), 1e-9);
  EXPECT_NE(doc["fle_source"].get<std::string>().find("estimated"), std::string::npos);
  EXPECT_GT(doc["predicted_tre_rms_mm"][1].get<double>(), doc["predicted_tre_rms_mm"][0].get<double>());

  // With --fle-mm the given value is used.
  ASSERT_EQ(run("register-points --fixed " + path("fixed.json") + " --moving " + path("moving.json") + " --targets " +
                path("targets.json") + " --fle-mm 0.5 --out " + path("r2.json")).code, 0);
  const json r2 = read_json(path("r2.json"));
  EXPECT_EQ(r2["fle_rms_mm"].get<double>(), 0.5);
  // ... and checked against the residuals: 0.5 mm explains 0.2 mm wobbles.
  ASSERT_TRUE(r2.contains("fle_check"));
  EXPECT_TRUE(r2["fle_check"]["consistent"].get<bool>());
  EXPECT_NEAR(r2["fle_check"]["fle_from_residuals_mm"].get<double>(), doc["fle_rms_mm"].get<double>(), 1e-9);
  EXPECT_FALSE(r2["fle_check"].contains("predicted_tre_rms_mm"));
  EXPECT_FALSE(doc.contains("fle_check"));  // estimated: nothing to check
  // An FLE of 0.02 mm cannot explain them: said on the output and in the file, with the TRE the
  // residuals' FLE predicts (the estimated run's), beside the optimistic one asked for.
  const CliResult small = run("register-points --fixed " + path("fixed.json") + " --moving " + path("moving.json") +
                              " --targets " + path("targets.json") + " --fle-mm 0.02 --out " + path("r3.json"));
  ASSERT_EQ(small.code, 0) << small.err;
  EXPECT_NE(small.out.find("more than --fle-mm 0.020 allows"), std::string::npos) << small.out;
  const json r3 = read_json(path("r3.json"));
  EXPECT_EQ(r3["status"], "ok");
  EXPECT_FALSE(r3["fle_check"]["consistent"].get<bool>());
  EXPECT_GT(r3["fle_check"]["chi2"].get<double>(), r3["fle_check"]["chi2_limit"].get<double>());
  ASSERT_EQ(r3["fle_check"]["predicted_tre_rms_mm"].size(), 2u);
  for (size_t k = 0; k < 2; ++k)
    EXPECT_NEAR(r3["fle_check"]["predicted_tre_rms_mm"][k].get<double>(), doc["predicted_tre_rms_mm"][k].get<double>(), 1e-9);
}

TEST_F(PointToolsCli, RegisterPointsWithWeights) {
  const std::vector<Eigen::Vector3d> moving = {{0, 0, 0}, {80, 10, 5}, {20, 90, -10}, {-30, 40, 60}, {60, 70, 40}};
  const Pose truth = pose_from_rotation_vector(Eigen::Vector3d(0.1, -0.2, 0.3), Eigen::Vector3d(5, 6, 7));
  std::vector<Eigen::Vector3d> fixed;
  for (const auto& m : moving) fixed.push_back(truth * m);
  fixed[2] += Eigen::Vector3d(3, 0, 0);  // one bad point, weighted down
  write_points("fixed.json", fixed);
  json m = {{"points", json::array()}, {"weights", {1, 1, 1e-6, 1, 1}}};
  for (const auto& p : moving) m["points"].push_back({p.x(), p.y(), p.z()});
  write_json(m, path("moving.json"));
  write_points("targets.json", {{25, 30, 25}});
  const CliResult r = run("register-points --fixed " + path("fixed.json") + " --moving " + path("moving.json") +
                          " --targets " + path("targets.json") + " --fle-mm 0.5 --out " + path("r.json"));
  ASSERT_EQ(r.code, 0) << r.err;
  const json doc = read_json(path("r.json"));
  EXPECT_TRUE(doc["weighted"].get<bool>());
  // The weighted-down point barely moves the result: the truth is recovered to within 0.01 mm.
  const Pose T = pose(doc["T_fixed_moving"]);
  for (const auto& p : moving) EXPECT_LT((T * p - truth * p).norm(), 0.01);
  // The point weighted down has a huge FLE of its own; the RMS FLE is 0.5 mm, so the other four's
  // are tiny and so is the predicted TRE.
  EXPECT_LT(doc["predicted_tre_rms_mm"][0].get<double>(), 0.05);
  m["weights"] = {1, 1, -1, 1, 1};
  write_json(m, path("bad.json"));
  expect_bad_input(run("register-points --fixed " + path("fixed.json") + " --moving " + path("bad.json") + " --out " +
                       path("r2.json")),
                   "bad.json", "r2.json");
  m["weights"] = {1, 1};
  write_json(m, path("short.json"));
  expect_bad_input(run("register-points --fixed " + path("fixed.json") + " --moving " + path("short.json") + " --out " +
                       path("r2.json")),
                   "short.json", "r2.json");
}

TEST_F(PointToolsCli, NumbersTooLargeForADoubleAreBadInput) {
  write_text("huge.json", R"({"points": [[1e400, 0, 0], [0, 1, 0], [0, 0, 1]]})");
  write_text("ok.json", R"({"points": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]})");
  expect_bad_input(run("register-points --fixed " + path("huge.json") + " --moving " + path("ok.json") + " --out " +
                       path("r.json")),
                   "huge.json", "r.json");
}

TEST_F(PointToolsCli, RegisterPointsBadInputAndCollinearPoints) {
  write_points("a.json", {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}});
  write_points("b.json", {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  expect_bad_input(run("register-points --fixed " + path("a.json") + " --moving " + path("b.json") + " --out " + path("r.json")),
                   "b.json", "r.json");
  write_text("null.json", "{\"points\": [[0,0,0], null, [0,1,0], [0,0,1]]}");
  expect_bad_input(run("register-points --fixed " + path("a.json") + " --moving " + path("null.json") + " --out " + path("r.json")),
                   "null.json", "r.json");
  write_text("nan.json", "{\"points\": [[0,0,0], [1,0,NaN], [0,1,0], [0,0,1]]}");
  expect_bad_input(run("register-points --fixed " + path("a.json") + " --moving " + path("nan.json") + " --out " + path("r.json")),
                   "nan.json", "r.json");
  expect_bad_input(run("register-points --fixed " + path("a.json") + " --moving " + path("a.json") + " --fle-mm -1 --out " +
                       path("r.json")),
                   "--fle-mm", "r.json");
  write_points("line.json", {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {5, 5, 5}});
  expect_failed(run("register-points --fixed " + path("a.json") + " --moving " + path("line.json") + " --out " + path("r.json")),
                "r.json", {"T_fixed_moving", "fre_rms_mm"});
}

TEST_F(PointToolsCli, IcpToStlMesh) {
  const TriangleMesh mesh = make_lumpy_surface(30);
  write_binary_stl("bone.stl", mesh);
  const Pose truth = pose_from_rotation_vector(Eigen::Vector3d(0.1, -0.3, 0.2), Eigen::Vector3d(5, 10, 400));
  std::vector<Eigen::Vector3d> points = sample_surface(mesh, 600, 4);
  for (auto& p : points) p = truth * p;
  points[0] += Eigen::Vector3d(0, 0, 15);  // an outlier
  write_points("points.json", points);
  const Pose start = truth * pose_from_rotation_vector(Eigen::Vector3d(0.1, 0.05, -0.05), Eigen::Vector3d(4, -5, 3));
  write_pose(start, path("init.json"));
  const CliResult r = run("icp --points " + path("points.json") + " --mesh " + path("bone.stl") + " --init " +
                          path("init.json") + " --out " + path("r.json"));
  ASSERT_EQ(r.code, 0) << r.err;
  const json doc = read_json(path("r.json"));
  EXPECT_EQ(doc["status"], "ok");
  expect_provenance(doc, "icp");
  EXPECT_EQ(doc["provenance"]["settings"]["surface"], "mesh");
  const Pose T = read_pose(path("r.json"));  // the result is a pose file
  double worst = 0;
  for (const auto& v : mesh.vertices) worst = std::max(worst, (T * v - truth * v).norm());
  EXPECT_LT(worst, 0.05);  // float vertices in the STL
  EXPECT_LT(doc["rms_mm"].get<double>(), 0.02);
  EXPECT_GE(doc["iterations"].get<int>(), 1);
  EXPECT_EQ(doc["keep_fraction"].get<double>(), 0.9);
  EXPECT_NEAR(doc["inlier_fraction"].get<double>(), 1.0, 0.01);
}

TEST_F(PointToolsCli, IcpBadInputAndUnreadableMesh) {
  write_points("points.json", sample_surface(make_lumpy_surface(8), 50, 1));
  write_pose(Pose::Identity(), path("init.json"));
  write_text("garbage.stl", "this is not a mesh");
  expect_bad_input(run("icp --points " + path("points.json") + " --mesh " + path("garbage.stl") + " --init " +
                       path("init.json") + " --out " + path("r.json")),
                   "garbage.stl", "r.json");
  expect_bad_input(run("icp --points " + path("points.json") + " --mesh " + path("missing.ply") + " --init " +
                       path("init.json") + " --out " + path("r.json")),
                   "missing.ply", "r.json");
  write_text("nan.json", "{\"points\": [[0,0,0], [1,0,NaN]]}");
  write_binary_stl("bone.stl", make_lumpy_surface(8));
  expect_bad_input(run("icp --points " + path("nan.json") + " --mesh " + path("bone.stl") + " --init " +
                       path("init.json") + " --out " + path("r.json")),
                   "nan.json", "r.json");
  expect_bad_input(run("icp --points " + path("points.json") + " --init " + path("init.json") + " --out " + path("r.json")),
                   "--mesh", "r.json");
  // Too few points for six pose parameters: readable, but the method cannot succeed.
  write_points("three.json", {{0, 0, 0}, {10, 0, 0}, {0, 10, 0}});
  expect_failed(run("icp --points " + path("three.json") + " --mesh " + path("bone.stl") + " --init " +
                    path("init.json") + " --out " + path("r.json")),
                "r.json", {"T_world_ct", "rms_mm"});
}

TEST_F(PointToolsCli, IcpToCtBoneSurface) {
  ASSERT_EQ(run("phantom --kind femur --size 64 --out " + path("ct.nii.gz")).code, 0);
  // Points on the CT's own surface at iso 250, as the command builds it (4 mm voxels, no coarsening).
  BoneMeshParams params;
  params.max_voxel_mm = 1.0;
  params.max_triangles = 2'000'000;
  const BoneMesh bone = bone_mesh_from_iso(read_volume(path("ct.nii.gz")), 250, params, "ct");
  const Pose truth = pose_from_rotation_vector(Eigen::Vector3d(1.2, 0, 0), Eigen::Vector3d(0, 0, 600));
  std::vector<Eigen::Vector3d> points = sample_surface(TriangleMesh{bone.vertices, bone.triangles}, 500, 8);
  for (auto& p : points) p = truth * p;
  write_points("points.json", points);
  write_pose(truth * pose_from_rotation_vector(Eigen::Vector3d(0, 0.08, 0.05), Eigen::Vector3d(3, 4, -5)),
             path("init.json"));
  const CliResult r = run("icp --points " + path("points.json") + " --ct " + path("ct.nii.gz") + " --iso 250 --init " +
                          path("init.json") + " --out " + path("r.json"));
  ASSERT_EQ(r.code, 0) << r.err;
  const Pose T = read_pose(path("r.json"));
  double sum = 0;
  for (const auto& v : bone.vertices) sum += (T * v - truth * v).norm();
  EXPECT_LT(sum / double(bone.vertices.size()), 0.05);
  EXPECT_EQ(read_json(path("r.json"))["surface"]["source"], "ct");
}

}  // namespace
}  // namespace fluoro
