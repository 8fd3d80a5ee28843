// Core types, files, phantoms and the backends (docs/python.md).
#include <chrono>
#include <cstring>
#include <optional>

#include "datasets/c_arm.hpp"
#include "datasets/phantom.hpp"
#include "engine/attenuation.hpp"
#include "engine/error.hpp"
#include "engine/image_io.hpp"
#include "engine/json_io.hpp"
#include "engine/volume_io.hpp"
#include "engine/xray.hpp"
#include "kernels/backend_registry.hpp"
#include "python/common.hpp"

namespace fluoro::py_bind {

using py::arg;

py::object json_to_python(const nlohmann::json& j) { return py::module_::import("json").attr("loads")(j.dump()); }

py::array_t<float> image_to_array(Image&& image) {
  auto* owned = new Image(std::move(image));
  py::capsule free_when_done(owned, [](void* p) { delete static_cast<Image*>(p); });
  return py::array_t<float>({py::ssize_t(owned->height), py::ssize_t(owned->width)},
                            {py::ssize_t(owned->width * sizeof(float)), py::ssize_t(sizeof(float))},
                            owned->pixels.data(), free_when_done);
}

Image array_to_image(const py::handle& array, const std::string& what) {
  const FloatArray a = FloatArray::ensure(array);
  if (!a || a.ndim() != 2) throw_input_error(what, "expected a 2D (height, width) array of numbers");
  Image image(int(a.shape(1)), int(a.shape(0)));
  std::memcpy(image.pixels.data(), a.data(), image.pixels.size() * sizeof(float));
  return image;
}

std::vector<Pose> poses_from_array(const py::handle& poses, bool* batched) {
  const DoubleArray a = DoubleArray::ensure(poses);
  if (!a) throw_input_error("poses", "expected an array of numbers");
  const bool batch = a.ndim() == 3;
  if (!((a.ndim() == 2 || batch) && (a.shape(a.ndim() - 2) == 4 || a.shape(a.ndim() - 2) == 3) &&
        a.shape(a.ndim() - 1) == 4))
    throw_input_error("poses", "expected a (4, 4) or (3, 4) array, or a batch (N, 4, 4) or (N, 3, 4)");
  if (batched) *batched = batch;
  const py::ssize_t n = batch ? a.shape(0) : 1, rows = a.shape(a.ndim() - 2);
  std::vector<Pose> out;
  out.reserve(size_t(n));
  for (py::ssize_t p = 0; p < n; ++p) {
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    const double* d = a.data() + p * rows * 4;
    for (int r = 0; r < rows; ++r)
      for (int c = 0; c < 4; ++c) m(r, c) = d[r * 4 + c];
    out.push_back(pose_from_matrix(m, batch ? "pose " + std::to_string(p) : "pose"));
  }
  return out;
}

py::array_t<double> pose_to_array(const Pose& p) {
  py::array_t<double> a({4, 4});
  auto r = a.mutable_unchecked<2>();
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) r(i, j) = p.matrix()(i, j);
  return a;
}

std::vector<PinholeCamera> cameras_from_object(const py::handle& cameras, bool* batched) {
  if (py::isinstance<PinholeCamera>(cameras)) {
    if (batched) *batched = false;
    return {cameras.cast<PinholeCamera>()};
  }
  if (batched) *batched = true;
  if (!py::isinstance<py::sequence>(cameras)) throw_input_error("cameras", "expected a Camera or a sequence of Cameras");
  std::vector<PinholeCamera> out;
  for (const auto& c : cameras.cast<py::sequence>()) {
    if (!py::isinstance<PinholeCamera>(c)) throw_input_error("cameras", "expected a Camera or a sequence of Cameras");
    out.push_back(c.cast<PinholeCamera>());
  }
  return out;
}

namespace {

template <int N, class T>
std::vector<Eigen::Matrix<T, N, 1>> points_from_array(const py::handle& h, const std::string& what) {
  const auto a = py::array_t<T, py::array::c_style | py::array::forcecast>::ensure(h);
  if (!a || (!(a.ndim() == 2 && a.shape(1) == N) && !(a.ndim() == 1 && a.shape(0) == 0)))
    throw_input_error(what, "expected an (M, " + std::to_string(N) + ") array of numbers");
  std::vector<Eigen::Matrix<T, N, 1>> out(a.ndim() == 2 ? size_t(a.shape(0)) : 0);
  for (size_t i = 0; i < out.size(); ++i)
    for (int c = 0; c < N; ++c) out[i][c] = a.data()[i * N + c];
  return out;
}

}  // namespace

std::vector<Eigen::Vector2f> points2f_from_array(const py::handle& a, const std::string& what) {
  return points_from_array<2, float>(a, what);
}
std::vector<Eigen::Vector3d> points3d_from_array(const py::handle& a, const std::string& what) {
  return points_from_array<3, double>(a, what);
}
py::array_t<double> points3d_to_array(const std::vector<Eigen::Vector3d>& p) {
  py::array_t<double> a({py::ssize_t(p.size()), py::ssize_t(3)});
  auto r = a.mutable_unchecked<2>();
  for (size_t i = 0; i < p.size(); ++i)
    for (int c = 0; c < 3; ++c) r(py::ssize_t(i), c) = p[i][c];
  return a;
}

namespace {

// A 3x3 direction given as a 3x3 array or SimpleITK's row-major 9-tuple.
Eigen::Matrix3d direction_from(const py::handle& h) {
  const DoubleArray a = DoubleArray::ensure(h);
  if (!a || a.size() != 9 || !(a.ndim() == 1 || (a.ndim() == 2 && a.shape(0) == 3)))
    throw_input_error("direction", "expected a 3x3 array or 9 numbers (row-major, as SimpleITK's GetDirection)");
  Eigen::Matrix3d d;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) d(r, c) = a.data()[r * 3 + c];
  return d;
}

Eigen::Vector3d vector3_from(const py::handle& h, const std::string& what) {
  const DoubleArray a = DoubleArray::ensure(h);
  if (!a || a.size() != 3 || a.ndim() != 1) throw_input_error(what, "expected 3 numbers (x, y, z)");
  return {a.data()[0], a.data()[1], a.data()[2]};
}

std::shared_ptr<Volume> make_volume(const py::handle& array, const py::object& origin, const py::object& spacing,
                                    const py::object& direction, const py::object& geometry) {
  const FloatArray a = FloatArray::ensure(array);
  if (!a || a.ndim() != 3) throw_input_error("volume", "expected a 3D (nz, ny, nx) array of numbers");
  auto v = std::make_shared<Volume>();
  v->geometry.size = Eigen::Vector3i(int(a.shape(2)), int(a.shape(1)), int(a.shape(0)));
  if (!geometry.is_none()) {
    const auto t = geometry.cast<py::sequence>();
    if (t.size() != 3) throw_input_error("geometry", "expected (origin, spacing, direction)");
    v->geometry.origin = vector3_from(t[0], "origin");
    v->geometry.spacing = vector3_from(t[1], "spacing");
    v->geometry.direction = direction_from(t[2]);
  }
  if (!origin.is_none()) v->geometry.origin = vector3_from(origin, "origin");
  if (!spacing.is_none()) v->geometry.spacing = vector3_from(spacing, "spacing");
  if (!direction.is_none()) v->geometry.direction = direction_from(direction);
  v->voxels.assign(a.data(), a.data() + a.size());
  validate_volume(*v, "volume");
  return v;
}

py::array_t<double> vec3_array(const Eigen::Vector3d& x) { return py::array_t<double>(3, x.data()); }
py::array_t<double> mat3_array(const Eigen::Matrix3d& m) {
  py::array_t<double> a({3, 3});
  auto r = a.mutable_unchecked<2>();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r(i, j) = m(i, j);
  return a;
}

void bind_geometry_properties(auto& cls) {
  using T = typename std::remove_reference_t<decltype(cls)>::type;
  auto geo = [](const T& v) -> const VolumeGeometry& {
    if constexpr (std::is_same_v<T, DeviceHandle>) return v.volume->geometry();
    else return v.geometry;
  };
  cls.def_property_readonly("size", [geo](const T& v) { return py::make_tuple(geo(v).size.x(), geo(v).size.y(), geo(v).size.z()); },
                            "voxels along (i, j, k) = (x, y, z)")
      .def_property_readonly("origin", [geo](const T& v) { return vec3_array(geo(v).origin); })
      .def_property_readonly("spacing", [geo](const T& v) { return vec3_array(geo(v).spacing); })
      .def_property_readonly("direction", [geo](const T& v) { return mat3_array(geo(v).direction); })
      .def_property_readonly("geometry", [geo](const T& v) {
            const auto& g = geo(v);
            py::tuple d(9);
            for (int i = 0; i < 9; ++i) d[size_t(i)] = g.direction(i / 3, i % 3);
            return py::make_tuple(py::make_tuple(g.origin.x(), g.origin.y(), g.origin.z()),
                                  py::make_tuple(g.spacing.x(), g.spacing.y(), g.spacing.z()), d);
          },
          "(origin, spacing, direction) as SimpleITK's GetOrigin, GetSpacing, GetDirection (row-major 9-tuple)");
}

struct PyPhantom {
  std::shared_ptr<Volume> hu;
  std::vector<Eigen::Vector3d> fiducials;
  double fiducial_radius_mm = 0;
};

// The array shape of a batch: the poses' batch dimension (if any), then the views' (if any).
std::vector<py::ssize_t> batch_shape(bool poses_batched, size_t n_poses, bool views_batched, size_t n_views) {
  std::vector<py::ssize_t> s;
  if (poses_batched) s.push_back(py::ssize_t(n_poses));
  if (views_batched) s.push_back(py::ssize_t(n_views));
  return s;
}

}  // namespace

void bind_core(py::module_& m) {
  // ---- volumes
  py::class_<Volume, std::shared_ptr<Volume>> volume(m, "Volume", R"(A CT (HU) or attenuation volume with ITK geometry.

Volume(array, origin=None, spacing=None, direction=None, geometry=None): `array` is (nz, ny, nx)
(voxel (i, j, k) is array[k, j, i], SimpleITK's GetArrayFromImage order), copied once as float32.
`geometry` is SimpleITK's (origin, spacing, direction) tuple; origin/spacing/direction override it.
Defaults: origin 0, spacing 1 mm, identity direction.)");
  volume.def(py::init(&make_volume), arg("array"), arg("origin") = py::none(), arg("spacing") = py::none(),
             arg("direction") = py::none(), arg("geometry") = py::none())
      .def_property_readonly(
          "array",
          [](py::object self) {
            auto& v = self.cast<Volume&>();
            const auto& s = v.geometry.size;
            return py::array_t<float>({py::ssize_t(s.z()), py::ssize_t(s.y()), py::ssize_t(s.x())},
                                      {py::ssize_t(sizeof(float)) * s.x() * s.y(), py::ssize_t(sizeof(float)) * s.x(),
                                       py::ssize_t(sizeof(float))},
                                      v.voxels.data(), self);
          },
          "the voxels as a writable (nz, ny, nx) float32 view (no copy; keeps the volume alive)")
      .def("index_to_physical",
           [](const Volume& v, const Eigen::Vector3d& ijk) { return vec3_array(v.geometry.index_to_physical(ijk)); },
           arg("ijk"))
      .def("physical_to_index",
           [](const Volume& v, const Eigen::Vector3d& x) { return vec3_array(v.geometry.physical_to_index(x)); },
           arg("x"))
      .def("__repr__", [](const Volume& v) {
        const auto& g = v.geometry;
        return "<fluoro.Volume " + std::to_string(g.size.x()) + "x" + std::to_string(g.size.y()) + "x" +
               std::to_string(g.size.z()) + ", spacing " + std::to_string(g.spacing.x()) + " " +
               std::to_string(g.spacing.y()) + " " + std::to_string(g.spacing.z()) + " mm>";
      });
  bind_geometry_properties(volume);

  m.def("read_volume", [](const std::string& path) {
    py::gil_scoped_release release;
    return std::make_shared<Volume>(read_volume(path));
  }, arg("path"), "NIfTI, MetaImage, NRRD or a DICOM directory, as float voxels with ITK's (LPS) geometry");
  m.def("write_volume", [](const Volume& v, const std::string& path) {
    py::gil_scoped_release release;
    write_volume(v, path);
  }, arg("volume"), arg("path"), "by extension (.nii, .nii.gz, .mha, .mhd, .nrrd), atomically");
  m.def("hu_to_attenuation", [](const Volume& hu, double mu_water_per_mm, double min_hu) {
    py::gil_scoped_release release;
    return std::make_shared<Volume>(hu_to_attenuation(hu, {mu_water_per_mm, min_hu}));
  }, arg("hu"), arg("mu_water_per_mm") = 0.02, arg("min_hu") = -1.0e30,
     "mu = mu_water * max(0, 1 + HU / 1000); voxels below min_hu become air (a new Volume)");

  // ---- images
  m.def("read_image", [](const std::string& path) {
    Image image;
    {
      py::gil_scoped_release release;
      image = read_image(path);
    }
    return image_to_array(std::move(image));
  }, arg("path"), "an (H, W) float32 array of the stored values; row 0 is the top row");
  m.def("write_image", [](const py::handle& a, const std::string& path) {
    const Image image = array_to_image(a, path);
    py::gil_scoped_release release;
    write_float_image(image, path);
  }, arg("image"), arg("path"), "raw float values: .tif/.tiff (32-bit float), .pfm, .nii/.nii.gz; atomically");
  // As `fluoro drr --out x.mha` does: .mha/.nrrd carry the detector's pixel pitch (the camera's
  // pixel_spacing_mm, or pixel_spacing_mm given here; 1 mm, i.e. pixel units, without either) and,
  // for a window, where its first pixel sits on the detector.
  m.def("write_drr", [](const py::handle& a, const std::string& path, const std::optional<PinholeCamera>& camera,
                        std::optional<Eigen::Vector2d> pixel_spacing_mm, std::optional<std::array<int, 2>> window_origin) {
    const Image image = array_to_image(a, path);
    if (pixel_spacing_mm && !(pixel_spacing_mm->allFinite() && pixel_spacing_mm->minCoeff() > 0))
      throw_input_error("pixel_spacing_mm", "must be two positive numbers");
    Eigen::Vector2d spacing = Eigen::Vector2d::Ones();
    if (camera && camera->pixel_spacing_mm) spacing = *camera->pixel_spacing_mm;
    if (pixel_spacing_mm) spacing = *pixel_spacing_mm;
    Eigen::Vector2d origin = Eigen::Vector2d::Zero();
    if (window_origin) origin = {spacing.x() * (*window_origin)[0], spacing.y() * (*window_origin)[1]};
    py::gil_scoped_release release;
    const LogDomainMapping mapping = write_drr(image, path, spacing, origin);
    return std::make_pair(mapping.a, mapping.b);
  }, arg("drr"), arg("path"), arg("camera") = py::none(), arg("pixel_spacing_mm") = py::none(),
     arg("window_origin") = py::none(),
     R"(as `fluoro drr` writes: raw line integrals, or for .png a 16-bit log-domain X-ray; returns (a, b) of the .png mapping.
.mha/.nrrd carry the pixel spacing: pixel_spacing_mm (column, row pitch) if given, else the camera's, else 1 (pixel units);
window_origin: the (x0, y0) of the window the DRR was rendered in (its first pixel's place on the detector).)");
  m.def("write_png", [](const py::handle& a, const std::string& path, float lo, float hi) {
    const Image image = array_to_image(a, path);
    py::gil_scoped_release release;
    write_png(image, path, lo, hi);
  }, arg("image"), arg("path"), arg("lo"), arg("hi"), "8-bit display PNG mapping [lo, hi] to [0, 255]");
  m.def("display_mapping", [](const py::handle& drr, double full_scale) {
    const LogDomainMapping mapping = display_mapping(array_to_image(drr, "drr"), full_scale);
    return std::make_pair(mapping.a, mapping.b);
  }, arg("drr"), arg("full_scale"), "(a, b) putting [0, max line integral] onto [full_scale, 0]");
  m.def("drr_to_xray", [](const py::handle& drr, double a, double b) {
    return image_to_array(drr_to_xray(array_to_image(drr, "drr"), {a, b}));
  }, arg("drr"), arg("a"), arg("b"), "a log-domain X-ray a - b * drr (float32)");

  // ---- cameras and poses
  py::class_<PinholeCamera>(m, "Camera", R"(A pinhole camera, OpenCV convention: x_cam = R x_world + t,
(u, v) = K x_cam / z, pixel (0, 0) the centre of the top-left pixel; u the column, v the row.)")
      .def(py::init([](const Eigen::Matrix3d& K, const Eigen::Matrix3d& R, const Eigen::Vector3d& t, int width,
                       int height, std::optional<Eigen::Vector2d> pixel_spacing_mm) {
             PinholeCamera c;
             c.K = K, c.R = R, c.t = t, c.width = width, c.height = height, c.pixel_spacing_mm = pixel_spacing_mm;
             validate_camera(c, "camera");
             return c;
           }),
           arg("K"), arg("R"), arg("t"), arg("width"), arg("height"), arg("pixel_spacing_mm") = py::none())
      .def_static("from_projection", [](const Eigen::Matrix<double, 3, 4>& P, int width, int height) {
        return camera_from_projection(P, width, height, "camera");
      }, arg("P"), arg("width"), arg("height"), "K, R, t from P = K [R | t] (3x4, any scale)")
      .def_static("look_at", &PinholeCamera::look_at, arg("source"), arg("target"), arg("down"), arg("focal_px"),
                  arg("width"), arg("height"))
      .def_readonly("width", &PinholeCamera::width)
      .def_readonly("height", &PinholeCamera::height)
      .def_property_readonly("K", [](const PinholeCamera& c) { return mat3_array(c.K); })
      .def_property_readonly("R", [](const PinholeCamera& c) { return mat3_array(c.R); })
      .def_property_readonly("t", [](const PinholeCamera& c) { return vec3_array(c.t); })
      .def_readonly("pixel_spacing_mm", &PinholeCamera::pixel_spacing_mm)
      .def_property_readonly("P", [](const PinholeCamera& c) { return Eigen::Matrix<double, 3, 4>(c.projection_matrix()); },
                             "K [R | t], 3x4")
      .def_property_readonly("source", [](const PinholeCamera& c) { return vec3_array(c.source()); })
      .def_property_readonly("camera_from_world", [](const PinholeCamera& c) { return pose_to_array(c.camera_from_world()); },
                             "[R | t] as a 4x4 rigid transform")
      .def("project", [](const PinholeCamera& c, const py::handle& points) {
        const auto p = points3d_from_array(points, "points");
        py::array_t<double> out({py::ssize_t(p.size()), py::ssize_t(2)});
        auto r = out.mutable_unchecked<2>();
        for (size_t i = 0; i < p.size(); ++i) {
          const Eigen::Vector2d uv = c.project(p[i]);
          r(py::ssize_t(i), 0) = uv.x(), r(py::ssize_t(i), 1) = uv.y();
        }
        return out;
      }, arg("points"), "(M, 3) world points to (M, 2) pixels (u, v); NaN behind the source")
      .def("__repr__", [](const PinholeCamera& c) {
        return "<fluoro.Camera " + std::to_string(c.width) + "x" + std::to_string(c.height) + ">";
      });
  m.def("read_camera", &read_camera, arg("path"));
  m.def("write_camera", &write_camera, arg("camera"), arg("path"));
  m.def("c_arm_view", [](double orbit_deg, double tilt_deg, int pixels, double pixel_mm, double source_to_isocentre_mm,
                         double source_to_detector_mm) {
    CArmGeometry g{source_to_isocentre_mm, source_to_detector_mm, pixels, pixel_mm};
    return c_arm_view(g, orbit_deg, tilt_deg);
  }, arg("orbit_deg"), arg("tilt_deg") = 0.0, arg("pixels") = 512, arg("pixel_mm") = 0.6,
     arg("source_to_isocentre_mm") = 600.0, arg("source_to_detector_mm") = 1000.0,
     "a synthetic C-arm view about the world origin (0: AP, 90: lateral), as the demo's");

  m.def("pose", [](const Eigen::Vector3d& rotation_vector, const Eigen::Vector3d& translation) {
    return pose_to_array(pose_from_rotation_vector(rotation_vector, translation));
  }, arg("rotation_vector"), arg("translation"), "a 4x4 rigid transform from axis * angle (radians) and mm");
  m.def("check_pose", [](const py::handle& a) {
    bool batched = false;
    const auto poses = poses_from_array(a, &batched);
    if (!batched) return py::object(pose_to_array(poses[0]));
    py::list out;
    for (const auto& p : poses) out.append(pose_to_array(p));
    return py::object(py::array(out));
  }, arg("pose"), "a (3, 4) or (4, 4) pose (or a batch) as validated 4x4 arrays; ValueError if not rigid");
  m.def("read_pose", [](const std::string& path) { return pose_to_array(read_pose(path)); }, arg("path"));
  m.def("write_pose", [](const py::handle& a, const std::string& path) {
    bool batched = false;
    const auto p = poses_from_array(a, &batched);
    if (batched) throw_input_error(path, "write_pose takes one pose");
    write_pose(p[0], path);
  }, arg("pose"), arg("path"));
  m.def("rotation_angle_deg", [](const py::handle& a) { return rotation_angle_deg(poses_from_array(a, nullptr)[0]); },
        arg("pose"));

  // ---- phantoms
  py::class_<PyPhantom>(m, "Phantom")
      .def_readonly("hu", &PyPhantom::hu, "the CT in HU, identity direction, centred on 0")
      .def_property_readonly("fiducials", [](const PyPhantom& p) { return points3d_to_array(p.fiducials); },
                             "(K, 3) sphere centres, CT frame, mm")
      .def_readonly("fiducial_radius_mm", &PyPhantom::fiducial_radius_mm);
  m.def("make_phantom", [](const std::string& kind, int size, double fov_mm, uint64_t seed, bool fiducials,
                           bool metal_object) {
    PhantomParams p;
    p.kind = parse_phantom_kind(kind);
    p.size = size, p.fov_mm = fov_mm, p.seed = seed, p.fiducials = fiducials, p.metal_object = metal_object;
    Phantom ph;
    {
      py::gil_scoped_release release;
      ph = make_phantom(p);
    }
    return PyPhantom{std::make_shared<Volume>(std::move(ph.hu)), ph.fiducials, ph.fiducial_radius_mm};
  }, arg("kind") = "femur", arg("size") = 128, arg("fov_mm") = 256.0, arg("seed") = 1, arg("fiducials") = false,
     arg("metal_object") = false, "a deterministic synthetic CT (femur or pelvis), as `fluoro phantom`");

  // ---- backends
  py::class_<DeviceHandle> device(m, "DeviceVolume", "a volume (1 component) or gradient field (3) on a backend");
  device.def_property_readonly("components", [](const DeviceHandle& h) { return h.volume->components(); });
  bind_geometry_properties(device);

  py::class_<Backend, std::shared_ptr<Backend>>(m, "Backend")
      .def_property_readonly("name", [](const Backend& b) { return std::string(b.name()); })
      .def("supports", [](const Backend& b, const std::string& op) {
        for (const Op o : kAllOps)
          if (op_name(o) == op) return b.supports(o);
        throw_input_error("op " + op, "unknown (gradient_field, drr, gradient_projection, gpr_score)");
      }, arg("op"))
      .def_property_readonly("prefers_batches", &Backend::prefers_batches)
      .def("upload", [](Backend& b, const Volume& mu) {
        py::gil_scoped_release release;
        return DeviceHandle{b.upload(mu)};
      }, arg("mu"), py::keep_alive<0, 1>(), "an attenuation volume (mu per mm) to the backend, once")
      .def("gradient_field", [](Backend& b, const DeviceHandle& mu, double sigma_mm, double resample_spacing_mm,
                                bool keep_coarser_axes) {
        py::gil_scoped_release release;
        return DeviceHandle{b.gradient_field(*mu.volume, {sigma_mm, resample_spacing_mm, keep_coarser_axes})};
      }, arg("mu"), arg("sigma_mm") = 1.0, arg("resample_spacing_mm") = 0.0, arg("keep_coarser_axes") = false,
         py::keep_alive<0, 1>(),
         "the Gaussian-derivative gradient of mu in the CT frame (1/mm^2), resident on the backend")
      .def("download_gradient", [](Backend& b, const DeviceHandle& g) {
        auto* field = new VectorField();
        {
          py::gil_scoped_release release;
          *field = b.download_gradient(*g.volume);
        }
        py::capsule owner(field, [](void* p) { delete static_cast<VectorField*>(p); });
        const auto& s = field->geometry.size;
        return py::array_t<float>({py::ssize_t(s.z()), py::ssize_t(s.y()), py::ssize_t(s.x()), py::ssize_t(3)},
                                  reinterpret_cast<const float*>(field->vectors.data()), owner);
      }, arg("gradient"), "the field as an (nz, ny, nx, 3) float32 array (x, y, z components; no copy)")
      .def("drr", [](Backend& b, const DeviceHandle& mu, const py::handle& poses, const py::handle& cameras,
                     double step_mm, std::optional<std::array<int, 4>> window) {
        bool poses_batched = false, views_batched = false;
        const auto p = poses_from_array(poses, &poses_batched);
        const auto v = cameras_from_object(cameras, &views_batched);
        DrrParams params;
        params.step_mm = step_mm;
        if (window) params.window = {(*window)[0], (*window)[1], (*window)[2], (*window)[3]};
        std::vector<Image> images;
        {
          py::gil_scoped_release release;
          images = b.drr(*mu.volume, p, v, params);
        }
        if (images.size() == 1 && !poses_batched && !views_batched) return image_to_array(std::move(images[0]));
        for (const auto& im : images)
          if (im.width != images[0].width || im.height != images[0].height)
            throw_input_error("drr", "views of different sizes cannot share one array: call drr once per view");
        auto shape = batch_shape(poses_batched, p.size(), views_batched, v.size());
        const int w = images.empty() ? (window ? (*window)[2] : 0) : images[0].width;
        const int h = images.empty() ? (window ? (*window)[3] : 0) : images[0].height;
        shape.push_back(h), shape.push_back(w);
        py::array_t<float> out(shape);
        float* dst = out.mutable_data();
        for (const auto& im : images) dst = std::copy(im.pixels.begin(), im.pixels.end(), dst);
        return out;
      }, arg("mu"), arg("poses"), arg("cameras"), arg("step_mm") = 1.0, arg("window") = py::none(),
         R"(DRRs (line integrals of mu, mm * 1/mm) of every (pose, camera) pair, float32.
poses: (4, 4)/(3, 4) or (N, 4, 4)/(N, 3, 4) T_world_ct; cameras: a Camera or a list of V.
Shape: [N,] [V,] H, W (the batch axes only when given as batches); row 0 the top row.
window: (x0, y0, width, height) renders only those pixels.)")
      .def("gpr_score", [](Backend& b, const DeviceHandle& g, const py::handle& poses, const py::handle& cameras,
                           const py::sequence& edges, double step_mm, double max_angle_deg, const std::string& sampling) {
        bool poses_batched = false;
        const auto p = poses_from_array(poses, &poses_batched);
        const auto v = cameras_from_object(cameras, nullptr);
        std::vector<EdgePixels> e;
        for (size_t i = 0; i < edges.size(); ++i) {
          const auto pair = edges[i].cast<py::sequence>();
          if (pair.size() != 2) throw_input_error("edges", "expected one (pixels, directions) pair per view");
          e.push_back({points2f_from_array(pair[0], "edges " + std::to_string(i) + " pixels"),
                       points2f_from_array(pair[1], "edges " + std::to_string(i) + " directions")});
        }
        GprParams params;
        params.projection.step_mm = step_mm;
        if (sampling == "nearest") params.projection.sampling = Sampling::nearest;
        else if (sampling != "trilinear") throw_input_error("sampling " + sampling, "expected trilinear or nearest");
        params.max_angle_deg = max_angle_deg;
        std::vector<double> scores;
        {
          py::gil_scoped_release release;
          scores = b.gpr_score(*g.volume, p, v, e, params);
        }
        if (!poses_batched) return py::object(py::float_(scores[0]));
        return py::object(py::array_t<double>(py::ssize_t(scores.size()), scores.data()));
      }, arg("gradient"), arg("poses"), arg("cameras"), arg("edges"), arg("step_mm") = 1.0,
         arg("max_angle_deg") = 30.0, arg("sampling") = "trilinear",
         "the GPR score per pose ((N,) float64, or a float for one pose); edges: per view (pixels (M, 2), directions (M, 2))")
      .def("gradient_projection", [](Backend& b, const DeviceHandle& g, const py::handle& poses,
                                     const py::handle& cameras, const py::sequence& pixels, double step_mm) {
        const auto p = poses_from_array(poses, nullptr);
        const auto v = cameras_from_object(cameras, nullptr);
        std::vector<std::vector<Eigen::Vector2f>> px;
        for (size_t i = 0; i < pixels.size(); ++i) px.push_back(points2f_from_array(pixels[i], "pixels " + std::to_string(i)));
        std::vector<std::vector<Eigen::Vector2f>> out;
        {
          py::gil_scoped_release release;
          out = b.gradient_projection(*g.volume, p, v, px, {step_mm, Sampling::trilinear});
        }
        py::list result;
        for (const auto& r : out) {
          py::array_t<float> a({py::ssize_t(r.size()), py::ssize_t(2)});
          std::memcpy(a.mutable_data(), r.data(), r.size() * sizeof(Eigen::Vector2f));
          result.append(a);
        }
        return result;
      }, arg("gradient"), arg("poses"), arg("cameras"), arg("pixels"), arg("step_mm") = 1.0,
         "expected image gradients (dDRR/du, dDRR/dv) at pixels[v]: a list, pose-major, of (M_v, 2) float32 arrays")
      .def("__repr__", [](const Backend& b) { return "<fluoro.Backend " + std::string(b.name()) + ">"; });
  m.def("make_backend", [](const std::string& name) { return std::shared_ptr<Backend>(make_backend(name)); },
        arg("name") = "cpu", "\"cpu\", \"reference\", \"vulkan[:N]\" (ValueError for an unknown name; BackendUnavailable)");
  m.def("backend_names", &backend_names);

  // For the overhead measurement (python/bench_overhead.py): the same drr call made `repeats`
  // times from C++, each timed alone (seconds), with no Python conversion in between.
  m.def("_drr_seconds_in_cpp", [](Backend& b, const DeviceHandle& mu, const py::handle& poses,
                                  const py::handle& cameras, double step_mm, int repeats,
                                  std::optional<std::array<int, 4>> window) {
    const auto p = poses_from_array(poses, nullptr);
    const auto v = cameras_from_object(cameras, nullptr);
    DrrParams params{step_mm, {}};
    if (window) params.window = {(*window)[0], (*window)[1], (*window)[2], (*window)[3]};
    std::vector<double> seconds;
    py::gil_scoped_release release;
    for (int r = 0; r < repeats; ++r) {
      const auto t0 = std::chrono::steady_clock::now();
      const auto images = b.drr(*mu.volume, p, v, params);
      seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      if (images.empty()) break;
    }
    return seconds;
  }, arg("backend"), arg("mu"), arg("poses"), arg("cameras"), arg("step_mm"), arg("repeats"), arg("window") = py::none());
}

}  // namespace fluoro::py_bind
