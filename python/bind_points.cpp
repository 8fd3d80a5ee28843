// The point tools (docs/python.md): pivot calibration, paired-point registration with its TRE
// prediction, and point-to-plane ICP to a mesh or a CT's bone surface, as `fluoro pivot`,
// `register-points` and `icp` run them. Results are the C++ structs; a failure is ok = False with a reason, as in C++.
#include <cmath>
#include <optional>

#include "engine/error.hpp"
#include "engine/mesh_io.hpp"
#include "engine/volume_io.hpp"
#include "pipelines/calibration/ct_surface.hpp"
#include "pipelines/calibration/icp.hpp"
#include "pipelines/calibration/paired_point_registration.hpp"
#include "pipelines/calibration/pivot_calibration.hpp"
#include "python/common.hpp"

namespace fluoro::py_bind {

using py::arg;

namespace {

// A mesh file's path, or (vertices (V, 3), triangles (T, 3)) with every index a vertex: the
// closest-point index reads vertices by these indices unchecked.
TriangleMesh mesh_from_object(const py::handle& mesh) {
  if (py::isinstance<py::str>(mesh)) return read_mesh(mesh.cast<std::string>());
  if (!py::isinstance<py::sequence>(mesh) || py::len(mesh) != 2)
    throw_input_error("mesh", "expected a mesh file's path or (vertices (V, 3), triangles (T, 3))");
  const py::sequence s = mesh.cast<py::sequence>();
  TriangleMesh out;
  out.vertices = points3d_from_array(s[0], "mesh vertices");
  const auto t = py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure(s[1]);
  if (!t || t.ndim() != 2 || t.shape(1) != 3) throw_input_error("mesh triangles", "expected a (T, 3) integer array");
  const auto r = t.unchecked<2>();
  for (py::ssize_t i = 0; i < t.shape(0); ++i) {
    std::array<int, 3> tri{};
    for (int c = 0; c < 3; ++c) {
      if (r(i, c) < 0 || r(i, c) >= (long long)out.vertices.size())
        throw_input_error("mesh triangles", "triangle " + std::to_string(i) + " has vertex index " +
                                                std::to_string(r(i, c)) + ", not one of the " +
                                                std::to_string(out.vertices.size()) + " vertices");
      tri[c] = int(r(i, c));
    }
    out.triangles.push_back(tri);
  }
  return out;
}

Pose one_pose(const py::handle& h, const std::string& what) {
  bool batched = false;
  const std::vector<Pose> p = poses_from_array(h, &batched);
  if (batched) throw_input_error(what, "expected one 4x4 pose, not a batch");
  return p[0];
}

}  // namespace

void bind_points(py::module_& m) {
  py::class_<PivotCalibration>(m, "PivotCalibration")
      .def_readonly("ok", &PivotCalibration::ok)
      .def_readonly("failure_reason", &PivotCalibration::failure_reason)
      .def_readonly("tip_in_tool", &PivotCalibration::tip_in_tool)
      .def_readonly("pivot_in_tracker", &PivotCalibration::pivot_in_tracker)
      .def_readonly("rms_mm", &PivotCalibration::rms_mm)
      .def_readonly("max_mm", &PivotCalibration::max_mm)
      .def_readonly("rotation_spread_deg", &PivotCalibration::rotation_spread_deg)
      .def_readonly("poses", &PivotCalibration::poses);
  m.def("pivot_calibration", [](const py::handle& poses, double min_rotation_deg) {
    if (!std::isfinite(min_rotation_deg) || min_rotation_deg < 0)
      throw_input_error("min_rotation_deg", "must be a non-negative number");
    bool batched = false;
    const std::vector<Pose> p = poses_from_array(poses, &batched);
    PivotParams params;
    params.min_rotation_spread_deg = min_rotation_deg;
    py::gil_scoped_release release;
    return pivot_calibration(p, params);
  }, arg("poses"), arg("min_rotation_deg") = PivotParams{}.min_rotation_spread_deg,
     "the pointer's tip (tool frame) and the pivot (tracker frame) from (N, 4, 4) T_tracker_tool poses");

  py::class_<PairedRegistration>(m, "PairedRegistration")
      .def_readonly("ok", &PairedRegistration::ok)
      .def_readonly("failure_reason", &PairedRegistration::failure_reason)
      .def_property_readonly("T_fixed_moving", [](const PairedRegistration& r) { return pose_to_array(r.T_fixed_moving); })
      .def_readonly("fre_rms_mm", &PairedRegistration::fre_rms_mm)
      .def_readonly("fre_max_mm", &PairedRegistration::fre_max_mm)
      .def_readonly("fle_rms_mm", &PairedRegistration::fle_rms_mm)
      .def_readonly("fle_estimated", &PairedRegistration::fle_estimated)
      .def_property_readonly("predicted_tre_rms_mm", [](const PairedRegistration& r) {
        return py::array_t<double>(py::ssize_t(r.predicted_tre_rms_mm.size()), r.predicted_tre_rms_mm.data());
      })
      .def_property_readonly("fle_check", [](const PairedRegistration& r) -> py::object {
        // None when the FLE was estimated from the residuals; else `fluoro register-points`'s fle_check.
        if (!r.fle_check) return py::none();
        const FleCheck& c = *r.fle_check;
        py::dict d;
        d["fle_from_residuals_mm"] = c.fle_from_residuals_mm;
        d["chi2"] = c.chi2;
        d["chi2_limit"] = c.chi2_limit;
        d["consistent"] = c.consistent;
        if (!c.consistent)
          d["predicted_tre_rms_mm"] = py::array_t<double>(py::ssize_t(c.predicted_tre_rms_mm.size()), c.predicted_tre_rms_mm.data());
        return d;
      });
  m.def("register_points", [](const py::handle& fixed, const py::handle& moving, const py::handle& weights,
                              const py::handle& targets, std::optional<double> fle_mm) {
    const auto f = points3d_from_array(fixed, "fixed");
    const auto mv = points3d_from_array(moving, "moving");
    if (f.size() != mv.size())
      throw_input_error("moving", std::to_string(mv.size()) + " points, but fixed has " + std::to_string(f.size()) +
                                      ": the lists must pair point by point");
    if (fle_mm && (!std::isfinite(*fle_mm) || *fle_mm < 0)) throw_input_error("fle_mm", "must be a non-negative number");
    std::vector<double> w;
    if (!weights.is_none()) {
      const DoubleArray a = DoubleArray::ensure(weights);
      if (!a || a.ndim() != 1 || size_t(a.shape(0)) != mv.size())
        throw_input_error("weights", "must hold one number per point (" + std::to_string(mv.size()) + ")");
      w.assign(a.data(), a.data() + a.shape(0));
      for (size_t i = 0; i < w.size(); ++i)
        if (!(w[i] > 0) || !std::isfinite(w[i])) throw_input_error("weights", "weight " + std::to_string(i) + " must be a positive number");
    }
    std::vector<Eigen::Vector3d> t;
    if (!targets.is_none()) t = points3d_from_array(targets, "targets");
    py::gil_scoped_release release;
    return register_paired_points(f, mv, t, fle_mm, w);
  }, arg("fixed"), arg("moving"), arg("weights") = py::none(), arg("targets") = py::none(), arg("fle_mm") = py::none(),
     "T_fixed_moving from paired (N, 3) points (Horn), the FRE, and the predicted TRE at targets (moving frame)");

  py::class_<IcpResult>(m, "IcpResult")
      .def_readonly("ok", &IcpResult::ok)
      .def_readonly("failure_reason", &IcpResult::failure_reason)
      .def_property_readonly("T_world_model", [](const IcpResult& r) { return pose_to_array(r.T_world_model); })
      .def_readonly("rms_mm", &IcpResult::rms_mm)
      .def_readonly("inlier_fraction", &IcpResult::inlier_fraction)
      .def_readonly("kept", &IcpResult::kept)
      .def_readonly("iterations", &IcpResult::iterations);
  // The CT as a Volume in HU or a path to one: its surface at iso_hu, as `fluoro icp --ct` builds it.
  const auto ct_surface = [](const py::handle& ct, double iso_hu, double ct_voxel_mm) {
    const bool path = py::isinstance<py::str>(ct);
    if (!path && !py::isinstance<Volume>(ct)) throw_input_error("ct", "expected a Volume (HU) or a volume file's path");
    const std::string what = path ? ct.cast<std::string>() : "ct";
    std::shared_ptr<Volume> read;
    const Volume* hu = nullptr;
    if (path) {
      py::gil_scoped_release release;
      read = std::make_shared<Volume>(read_volume(what));
      hu = read.get();
    } else {
      hu = ct.cast<const Volume*>();
    }
    py::gil_scoped_release release;
    return ct_bone_surface(*hu, iso_hu, ct_voxel_mm, what);
  };
  m.def("ct_surface", [ct_surface](const py::handle& ct, double iso_hu, double ct_voxel_mm) {
    const TriangleMesh mesh = ct_surface(ct, iso_hu, ct_voxel_mm);
    py::array_t<int> triangles({py::ssize_t(mesh.triangles.size()), py::ssize_t(3)});
    auto t = triangles.mutable_unchecked<2>();
    for (size_t i = 0; i < mesh.triangles.size(); ++i)
      for (int c = 0; c < 3; ++c) t(py::ssize_t(i), c) = mesh.triangles[i][size_t(c)];
    return py::make_tuple(points3d_to_array(mesh.vertices), triangles);
  }, arg("ct"), arg("iso_hu") = 250.0, arg("ct_voxel_mm") = 1.0,
     "(vertices (V, 3) float64 mm in the CT frame, triangles (T, 3) int32): the bone surface `fluoro icp --ct` registers to");
  m.def("icp", [ct_surface](const py::handle& points, const py::handle& mesh, const py::handle& initial,
                            double keep_fraction, int max_iterations, const py::handle& ct, double iso_hu,
                            double ct_voxel_mm) {
    if (mesh.is_none() == ct.is_none()) throw_input_error("icp", "give mesh (a file or (vertices, triangles)) or ct");
    if (!(keep_fraction > 0 && keep_fraction <= 1)) throw_input_error("keep_fraction", "must be in (0, 1]");
    if (max_iterations < 1) throw_input_error("max_iterations", "must be at least 1");
    const auto p = points3d_from_array(points, "points");
    const Pose init = initial.is_none() ? Pose::Identity() : one_pose(initial, "initial");
    const TriangleMesh surface = ct.is_none() ? mesh_from_object(mesh) : ct_surface(ct, iso_hu, ct_voxel_mm);
    IcpParams params;
    params.keep_fraction = keep_fraction;
    params.max_iterations = max_iterations;
    py::gil_scoped_release release;
    const MeshClosestPoint index(surface, ct.is_none() ? "mesh" : "ct");  // the BVH build is the long part for a big mesh
    return icp_point_to_plane(index, p, init, params);
  }, arg("points"), arg("mesh") = py::none(), arg("initial") = py::none(),
     arg("keep_fraction") = IcpParams{}.keep_fraction, arg("max_iterations") = IcpParams{}.max_iterations,
     arg("ct") = py::none(), arg("iso_hu") = 250.0, arg("ct_voxel_mm") = 1.0,
     "T_world_model putting the model through the (N, 3) world points, trimmed point-to-plane: the model is a mesh "
     "(path, or (vertices, triangles)) or a CT (Volume in HU or path) whose bone surface at iso_hu is used, as "
     "`fluoro icp --ct` (CT box-averaged to about ct_voxel_mm first)");
}

}  // namespace fluoro::py_bind
