#pragma once
// Shared by the binding files: array conversions and the handle types (docs/python.md).
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "engine/backend.hpp"
#include "engine/camera.hpp"
#include "engine/image.hpp"
#include "engine/pose.hpp"
#include "engine/volume.hpp"

namespace fluoro::py_bind {

namespace py = pybind11;
using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;
using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

// A handle to a volume on a backend. The Python object keeps its backend alive (keep_alive).
struct DeviceHandle {
  std::shared_ptr<const DeviceVolume> volume;
};

// A JSON document as the Python objects json.loads makes of it (dicts, lists, numbers, strings).
py::object json_to_python(const nlohmann::json& j);

// An (H, W) float32 array that owns the image's buffer (no copy).
py::array_t<float> image_to_array(Image&& image);
// A copy of an (H, W) array (any real dtype) as an Image.
Image array_to_image(const py::handle& array, const std::string& what);

// Poses: (4, 4) or (3, 4) gives one pose, (N, 4, 4) or (N, 3, 4) a batch. Each must be a proper
// rigid transform (ValueError otherwise). `batched` tells which form was given.
std::vector<Pose> poses_from_array(const py::handle& poses, bool* batched);
py::array_t<double> pose_to_array(const Pose& p);

// One Camera or a sequence of them; `batched` tells which.
std::vector<PinholeCamera> cameras_from_object(const py::handle& cameras, bool* batched);

// (M, 2) / (M, 3) arrays to and from point lists.
std::vector<Eigen::Vector2f> points2f_from_array(const py::handle& a, const std::string& what);
std::vector<Eigen::Vector3d> points3d_from_array(const py::handle& a, const std::string& what);
py::array_t<double> points3d_to_array(const std::vector<Eigen::Vector3d>& p);

void bind_core(py::module_& m);
void bind_pipelines(py::module_& m);
void bind_calibration(py::module_& m);
void bind_points(py::module_& m);
void bind_panorama(py::module_& m);

}  // namespace fluoro::py_bind
