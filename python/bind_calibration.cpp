// The calibration and distal-locking entry points (docs/python.md): the dewarp fit and the camera
// calibration return the documents `fluoro dewarp fit` and `fluoro calibrate` write (as dicts,
// without the inputs' digests and timings); distal locking returns an object, and the robot's goal
// from it the fields `fluoro distal-lock --robot` adds.
#include <optional>

#include "engine/distal_locking_models.hpp"
#include "engine/error.hpp"
#include "engine/grid_model.hpp"
#include "engine/phantom_model.hpp"
#include "pipelines/calibration/dewarp_fit.hpp"
#include "pipelines/calibration/dewarp_map.hpp"
#include "pipelines/calibration/image_calibration.hpp"
#include "pipelines/distal_locking/distal_locking.hpp"
#include "pipelines/distal_locking/robot_goal.hpp"
#include "python/common.hpp"

namespace fluoro::py_bind {

using py::arg;

namespace {

void check_size(const Image& image, int width, int height, const std::string& what, const std::string& describes) {
  if (image.width != width || image.height != height)
    throw_input_error("image", "is " + std::to_string(image.width) + "x" + std::to_string(image.height) + ", " + what +
                                   " " + describes + " " + std::to_string(width) + "x" + std::to_string(height) +
                                   " images");
}

}  // namespace

void bind_calibration(py::module_& m) {
  m.def("fit_dewarp", [](const py::handle& image, const std::string& grid_path, const std::string& model) {
    const GridModel grid = read_grid_model(grid_path);
    const Image im = array_to_image(image, "image");
    DewarpFitOptions options;
    options.model = parse_dewarp_model(model);
    DewarpFit fit;
    {
      py::gil_scoped_release release;
      fit = fit_dewarp(im, grid, options);
    }
    return json_to_python(dewarp_fit_document(fit, grid, im.width, im.height));
  }, arg("image"), arg("grid"), arg("model") = "polynomial",
     "the dewarp map fitted to a grid X-ray (GRID.json path): the MAP.json document as a dict ('status' ok or failed)");

  m.def("calibrate_image", [](const py::handle& image, const std::string& phantom_path,
                              std::optional<std::string> dewarp_path) {
    const PhantomModel phantom = read_phantom_model(phantom_path);
    const Image im = array_to_image(image, "image");
    std::optional<DewarpMap> map;
    if (dewarp_path) {
      map = DewarpMap::read(*dewarp_path);
      check_size(im, map->width(), map->height(), "the map", *dewarp_path + " corrects");
    }
    ImageCalibration result;
    {
      py::gil_scoped_release release;
      result = calibrate_image(im, phantom, map ? &*map : nullptr);
    }
    return json_to_python(calibration_document(result, phantom));
  }, arg("image"), arg("phantom"), arg("dewarp") = py::none(),
     "the camera from a phantom X-ray (PHANTOM.json path, optional MAP.json path): the CAMERA.json document as a dict");

  py::class_<DistalLocking>(m, "DistalLocking")
      .def_readonly("ok", &DistalLocking::ok)
      .def_readonly("failure_reason", &DistalLocking::failure_reason)
      .def_readonly("guide_ok", &DistalLocking::guide_ok)
      .def_readonly("nail_ok", &DistalLocking::nail_ok)
      .def_property_readonly("T_world_guide", [](const DistalLocking& r) { return pose_to_array(r.T_world_guide); })
      .def_property_readonly("T_world_nail", [](const DistalLocking& r) { return pose_to_array(r.T_world_nail); })
      .def_property_readonly("T_camera_guide", [](const DistalLocking& r) { return pose_to_array(r.T_camera_guide); })
      .def_property_readonly("T_camera_nail", [](const DistalLocking& r) { return pose_to_array(r.T_camera_nail); })
      .def_property_readonly("holes", [](const DistalLocking& r) {
        py::list holes;
        for (const auto& h : r.holes) {
          py::dict d;
          d["entry_mm"] = Eigen::Vector3d(h.entry_mm);
          d["exit_mm"] = Eigen::Vector3d(h.exit_mm);
          d["circularity"] = h.circularity;
          d["deviation_deg"] = h.deviation_deg;
          holes.append(d);
        }
        return holes;
      }, "per hole of NAIL.json: entry_mm, exit_mm (world), circularity, deviation_deg");
  m.def("locate_for_distal_locking", [](const py::handle& image, const PinholeCamera& camera,
                                        const std::string& guide_path, const std::string& nail_path,
                                        const std::string& mode) {
    if (mode != "generic" && mode != "interactive")
      throw_input_error("mode", "must be generic or interactive, not " + mode);
    const DrillGuideModel guide = read_drill_guide_model(guide_path);
    const NailModel nail = read_nail_model(nail_path);
    const Image im = array_to_image(image, "image");
    check_size(im, camera.width, camera.height, "the camera", "describes");
    py::gil_scoped_release release;
    return locate_for_distal_locking(im, camera, guide, nail,
                                     mode == "interactive" ? NailMode::interactive : NailMode::generic);
  }, arg("image"), arg("camera"), arg("guide"), arg("nail"), arg("mode") = "generic",
     "the drill guide's and the nail's poses and the holes' entry and exit points from one X-ray (GUIDE.json, NAIL.json paths)");

  m.def("robot_goal", [](const DistalLocking& r, const std::string& guide_path, const std::string& nail_path,
                         const std::string& robot_path) {
    if (!r.ok) throw_input_error("robot_goal", "the distal locking failed (" + r.failure_reason + "): no poses to aim at");
    const DrillGuideModel guide = read_drill_guide_model(guide_path);
    const NailModel nail = read_nail_model(nail_path);
    const RobotModel robot = read_robot_model(robot_path);
    check_guide_fits_nail(guide, nail, guide_path, nail_path);  // as `fluoro distal-lock --robot`
    const RobotGoal goal = robot_goal(guide, nail, robot, r.T_camera_guide, r.T_camera_nail);
    py::dict d;
    d["T_base_goal"] = pose_to_array(goal.T_base_goal);
    d["slide_mm"] = goal.slide_mm;
    d["turn_from_now_deg"] = goal.turn_from_now_deg;
    d["spacing_mismatch_mm"] = goal.spacing_mismatch_mm;
    return d;
  }, arg("result"), arg("guide"), arg("nail"), arg("robot"),
     "the robot tip's goal pose in its base frame (ROBOT.json path) putting the guide's axes on the holes: "
     "a dict of T_base_goal, slide_mm, turn_from_now_deg, spacing_mismatch_mm");
}

}  // namespace fluoro::py_bind
