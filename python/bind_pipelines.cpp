// The 2D/3D registration, its edge pixels, start poses and error measures (docs/python.md); the
// initial pose from landmarks, traced (or livewire-clicked) contours and the ITK transform file, as
// `fluoro register --landmarks --contours [--livewire] --tfm` use them.
#include <cstring>

#include "engine/error.hpp"
#include "engine/itk_transform_writer.hpp"
#include "pipelines/registration/landmarks.hpp"
#include "pipelines/registration/livewire.hpp"
#include "pipelines/registration/registration_io.hpp"
#include "pipelines/registration/edge_pixels.hpp"
#include "pipelines/registration/error_metrics.hpp"
#include "pipelines/registration/registration.hpp"
#include "pipelines/registration/start_poses.hpp"
#include "python/common.hpp"

namespace fluoro::py_bind {

using py::arg;

namespace {

py::array_t<float> points2f_to_array(const std::vector<Eigen::Vector2f>& p) {
  py::array_t<float> a({py::ssize_t(p.size()), py::ssize_t(2)});
  if (!p.empty()) std::memcpy(a.mutable_data(), p.data(), p.size() * sizeof(Eigen::Vector2f));
  return a;
}

// Views as XrayView objects or (image, camera) / (name, image, camera) tuples.
std::vector<XrayView> views_from(const py::sequence& views) {
  std::vector<XrayView> out;
  for (size_t i = 0; i < views.size(); ++i) {
    const py::handle v = views[i];
    if (py::isinstance<XrayView>(v)) {
      out.push_back(v.cast<XrayView>());
      continue;
    }
    const auto t = v.cast<py::sequence>();
    const std::string name = t.size() == 3 ? t[0].cast<std::string>() : "view " + std::to_string(i);
    if (t.size() != 2 && t.size() != 3) throw_input_error("views", "expected (image, camera) or (name, image, camera)");
    out.push_back({name, array_to_image(t[t.size() - 2], name), t[t.size() - 1].cast<PinholeCamera>()});
  }
  return out;
}

}  // namespace

void bind_pipelines(py::module_& m) {
  py::class_<XrayView>(m, "XrayView", "an X-ray in the log domain (bone dark) and its camera")
      .def(py::init([](const py::handle& image, const PinholeCamera& camera, const std::string& name) {
             return XrayView{name, array_to_image(image, name), camera};
           }),
           arg("image"), arg("camera"), arg("name") = "view")
      .def_readonly("name", &XrayView::name)
      .def_readonly("camera", &XrayView::camera)
      .def_property_readonly("image", [](const XrayView& v) { return image_to_array(Image(v.image)); },
                             "a copy of the image, (H, W) float32");

  py::class_<GprStage>(m, "GprStage")
      .def(py::init<>())
      .def_readwrite("sigma_mm", &GprStage::sigma_mm)
      .def_readwrite("grid_mm", &GprStage::grid_mm)
      .def_readwrite("step_mm", &GprStage::step_mm)
      .def_readwrite("gradient_floor", &GprStage::gradient_floor)
      .def_readwrite("max_pixels", &GprStage::max_pixels)
      .def_readwrite("rotation_step_deg", &GprStage::rotation_step_deg)
      .def_readwrite("translation_step_mm", &GprStage::translation_step_mm)
      .def_property("max_iterations", [](const GprStage& s) { return s.simplex.max_iterations; },
                    [](GprStage& s, int n) { s.simplex.max_iterations = n; });

  py::class_<RegistrationOptions>(m, "RegistrationOptions", "the registration's options (registration.hpp documents each)")
      .def(py::init<>())
      .def_readwrite("mu_water_per_mm", &RegistrationOptions::mu_water_per_mm)
      .def_readwrite("bone_iso_hu", &RegistrationOptions::bone_iso_hu)
      .def_readwrite("tissue_hu", &RegistrationOptions::tissue_hu)
      .def_readwrite("coarse", &RegistrationOptions::coarse)
      .def_readwrite("coarse_restarts", &RegistrationOptions::coarse_restarts)
      .def_readwrite("stages", &RegistrationOptions::stages)
      .def_readwrite("final_restarts", &RegistrationOptions::final_restarts)
      .def_readwrite("max_angle_deg", &RegistrationOptions::max_angle_deg)
      .def_readwrite("min_gradient_correlation", &RegistrationOptions::min_gradient_correlation)
      .def_readwrite("min_view_correlation", &RegistrationOptions::min_view_correlation)
      .def_readwrite("min_confident_correlation", &RegistrationOptions::min_confident_correlation)
      .def_readwrite("min_relative_correlation", &RegistrationOptions::min_relative_correlation)
      .def_property(
          "correlation_polish",
          [](const RegistrationOptions& o) { return std::string(correlation_polish_name(o.correlation_polish)); },
          [](RegistrationOptions& o, const std::string& name) {
            const std::optional<CorrelationPolish> mode = correlation_polish_from_name(name);
            if (!mode) throw py::value_error("correlation_polish must be \"auto\", \"on\" or \"off\", not \"" + name + "\"");
            o.correlation_polish = *mode;
          },
          "\"auto\" (default), \"on\" or \"off\": the last stage maximising the gradient correlation")
      .def_readwrite("polish_below_relative_correlation", &RegistrationOptions::polish_below_relative_correlation);

  py::class_<StageReport>(m, "StageReport")
      .def_readonly("name", &StageReport::name)
      .def_readonly("seconds", &StageReport::seconds)
      .def_readonly("iterations", &StageReport::iterations)
      .def_readonly("evaluations", &StageReport::evaluations)
      .def_readonly("value", &StageReport::value)
      .def_readonly("converged", &StageReport::converged)
      .def_property_readonly("pose", [](const StageReport& s) { return pose_to_array(s.pose); })
      .def("__repr__", [](const StageReport& s) {
        return "<fluoro.StageReport " + s.name + ": " + std::to_string(s.iterations) + " iterations, value " +
               std::to_string(s.value) + ", " + std::to_string(s.seconds) + " s>";
      });

  py::class_<RegistrationReport>(m, "RegistrationReport")
      .def_property_readonly("initial", [](const RegistrationReport& r) { return pose_to_array(r.initial); })
      .def_property_readonly("pose", [](const RegistrationReport& r) { return pose_to_array(r.pose); },
                             "the registered T_world_ct, 4x4")
      .def_readonly("ok", &RegistrationReport::ok)
      .def_readonly("failure_reason", &RegistrationReport::failure_reason)
      .def_readonly("score", &RegistrationReport::score)
      .def_readonly("gradient_correlation", &RegistrationReport::gradient_correlation)
      .def_readonly("view_correlations", &RegistrationReport::view_correlations)
      .def_readonly("confident", &RegistrationReport::confident)
      .def_readonly("expected_correlation", &RegistrationReport::expected_correlation)
      .def_readonly("expected_view_correlations", &RegistrationReport::expected_view_correlations)
      .def_property_readonly("relative_view_correlations",
                             [](const RegistrationReport& r) { return r.relative_view_correlations(); })
      .def_property_readonly("relative_correlation", &RegistrationReport::relative_correlation)
      .def_readonly("relative_correlation_floor", &RegistrationReport::relative_correlation_floor)
      .def_readonly("stages", &RegistrationReport::stages)
      .def_readonly("seconds", &RegistrationReport::seconds)
      .def("__repr__", [](const RegistrationReport& r) {
        return std::string("<fluoro.RegistrationReport ") + (r.ok ? "ok" : "failed: " + r.failure_reason) +
               (r.confident ? ", confident" : ", not confident") + ", correlation " +
               std::to_string(r.gradient_correlation) + ", " + std::to_string(r.seconds) + " s>";
      });

  py::class_<PreparedRegistration>(m, "PreparedRegistration", R"(The CT to X-ray registration, prepared once per CT and set of X-rays.

PreparedRegistration(backend, hu, views, options=None, mask=None, contours=None, livewire=False): hu
is the CT in HU (Volume); views a list of XrayView or (image, camera) / (name, image, camera) tuples,
images in the log domain (bone dark); contours a CONTOURS.json path traced on the X-rays (livewire:
its polylines' vertices are clicks joined along the X-ray's edges), as `fluoro register --contours`.
run(initial_pose) -> RegistrationReport; run is thread-safe and releases the GIL.)")
      .def(py::init([](Backend& backend, const Volume& hu, const py::sequence& views,
                       std::optional<RegistrationOptions> options, const Volume* mask,
                       std::optional<std::string> contours_path, bool livewire) {
             auto v = views_from(views);
             const RegistrationOptions o = options.value_or(RegistrationOptions{});
             if (livewire && !contours_path) throw_input_error("livewire", "needs contours (the clicked points' file)");
             py::gil_scoped_release release;
             // As `fluoro register --contours [--livewire]`: traced contours sampled along their
             // polylines, or each polyline's vertices as clicks joined along the X-ray's edges.
             std::vector<std::vector<Eigen::Vector2f>> contours;
             if (contours_path) {
               std::vector<int> w, h;
               for (const XrayView& view : v) w.push_back(view.camera.width), h.push_back(view.camera.height);
               if (!livewire) {
                 contours = read_contours(*contours_path, w, h);
               } else {
                 const auto polylines = read_contour_polylines(*contours_path, w, h);
                 contours.resize(v.size());
                 for (size_t i = 0; i < v.size(); ++i)
                   for (const Polyline& clicks : polylines[i])
                     for (const auto& p : livewire_path(v[i].image, clicks)) contours[i].push_back(p);
               }
             }
             return std::make_unique<PreparedRegistration>(backend, hu, std::move(v), o, mask, contours);
           }),
           arg("backend"), arg("hu"), arg("views"), arg("options") = py::none(), arg("mask") = py::none(),
           arg("contours") = py::none(), arg("livewire") = false, py::keep_alive<1, 2>())
      .def("run", [](const PreparedRegistration& r, const py::handle& initial) {
        const Pose p = poses_from_array(initial, nullptr)[0];
        py::gil_scoped_release release;
        return r.run(p);
      }, arg("initial"), "register from the initial T_world_ct (4x4 or 3x4)")
      .def("gradient_correlation", [](const PreparedRegistration& r, const py::handle& pose) {
        const Pose p = poses_from_array(pose, nullptr)[0];
        py::gil_scoped_release release;
        return r.gradient_correlation(p);
      }, arg("pose"))
      .def_property_readonly("preparation_seconds", &PreparedRegistration::preparation_seconds)
      .def_property_readonly("bone_centre", [](const PreparedRegistration& r) { return Eigen::Vector3d(r.bone_centre()); });

  m.def("register_landmarks", [](const std::string& path, const py::handle& cameras) {
    const std::vector<PinholeCamera> c = cameras_from_object(cameras, nullptr);
    LandmarkRegistration l;
    {
      py::gil_scoped_release release;
      l = register_landmarks(read_landmarks(path, c.size()), c, path);
    }
    py::dict d;
    d["T_world_ct"] = pose_to_array(l.registration.transform);
    d["landmarks_used"] = l.ray_distance_mm.size();
    d["fre_rms_mm"] = l.registration.rms_mm;
    d["fre_max_mm"] = l.registration.max_mm;
    d["ray_distance_mm"] = l.ray_distance_mm;
    return d;
  }, arg("landmarks"), arg("cameras"),
     "the initial pose `fluoro register --landmarks` starts from: LANDMARKS.json (CT points and their pixels in "
     "each view) and the views' cameras; a dict T_world_ct landmarks_used fre_rms_mm fre_max_mm ray_distance_mm");
  m.def("write_itk_transform", [](const py::handle& pose, const std::string& path) {
    const Pose p = poses_from_array(pose, nullptr)[0];
    if (!is_itk_transform_path(path)) throw_input_error(path, "unsupported transform file extension (use .tfm, .txt, .h5 or .hdf5)");
    py::gil_scoped_release release;
    write_itk_transform(p, path);
  }, arg("T_world_ct"), arg("path"),
     "as `fluoro register --tfm`: T_world_ct^-1 (world to CT, ITK's fixed-to-moving) as an ITK transform file "
     "(.tfm/.txt text, .h5/.hdf5), for 3D Slicer and SimpleITK");

  m.def("detect_edge_pixels", [](const py::handle& xray, bool bone_dark, double low_fraction, double high_fraction,
                                 double blur_sigma_px, int max_pixels) {
    const Image image = array_to_image(xray, "xray");
    EdgeDetectionParams params;
    params.low_fraction = low_fraction, params.high_fraction = high_fraction;
    params.blur_sigma_px = blur_sigma_px, params.max_pixels = max_pixels;
    EdgePixels e;
    {
      py::gil_scoped_release release;
      e = detect_edge_pixels(image, bone_dark ? XrayPolarity::log_domain : XrayPolarity::bone_bright, params, "xray");
    }
    return py::make_tuple(points2f_to_array(e.pixels), points2f_to_array(e.directions));
  }, arg("xray"), arg("bone_dark") = true, arg("low_fraction") = 0.05, arg("high_fraction") = 0.15,
     arg("blur_sigma_px") = 1.0, arg("max_pixels") = 0,
     "Canny edge pixels (M, 2) (u, v) and the unit directions (M, 2) the expected gradient should have: gpr_score's edges");

  py::class_<RegistrationErrors>(m, "RegistrationErrors")
      .def_readonly("surface_tre_mean_mm", &RegistrationErrors::surface_tre_mean_mm)
      .def_readonly("surface_tre_max_mm", &RegistrationErrors::surface_tre_max_mm)
      .def_readonly("fiducial_tre_mean_mm", &RegistrationErrors::fiducial_tre_mean_mm)
      .def_readonly("mpd_mm", &RegistrationErrors::mpd_mm)
      .def_readonly("rotation_deg", &RegistrationErrors::rotation_deg)
      .def_readonly("translation_mm", &RegistrationErrors::translation_mm)
      .def("__repr__", [](const RegistrationErrors& e) {
        char s[256];
        std::snprintf(s, sizeof s,
                      "<fluoro.RegistrationErrors surface TRE %.3f mm (max %.3f), fiducial TRE %.3f mm, mPD %.3f mm, "
                      "rotation %.3f deg, translation %.3f mm>",
                      e.surface_tre_mean_mm, e.surface_tre_max_mm, e.fiducial_tre_mean_mm, e.mpd_mm, e.rotation_deg,
                      e.translation_mm);
        return std::string(s);
      });
  m.def("registration_errors", [](const py::handle& estimate, const py::handle& truth, const py::handle& surface,
                                  const py::handle& fiducials, const py::handle& cameras) {
    const auto views = cameras.is_none() ? std::vector<PinholeCamera>{} : cameras_from_object(cameras, nullptr);
    const auto fid = fiducials.is_none() ? std::vector<Eigen::Vector3d>{} : points3d_from_array(fiducials, "fiducials");
    return registration_errors(poses_from_array(estimate, nullptr)[0], poses_from_array(truth, nullptr)[0],
                               points3d_from_array(surface, "surface_points"), fid, views);
  }, arg("estimate"), arg("truth"), arg("surface_points"), arg("fiducials") = py::none(), arg("cameras") = py::none(),
     "errors of T_world_ct estimate against truth; points (M, 3) in the CT frame");
  m.def("surface_points", [](const Volume& hu, double iso_hu, size_t max_points) {
    std::vector<Eigen::Vector3d> p;
    {
      py::gil_scoped_release release;
      p = surface_points(hu, iso_hu, max_points);
    }
    return points3d_to_array(p);
  }, arg("hu"), arg("iso_hu") = 250.0, arg("max_points") = 2000, "(M, 3) bone surface points, CT frame");
  m.def("mean_point", [](const py::handle& points) { return Eigen::Vector3d(mean_point(points3d_from_array(points, "points"))); },
        arg("points"));
  m.def("start_pose_at_distance", [](const py::handle& truth, const py::handle& surface, const Eigen::Vector3d& centre,
                                     double distance_mm, uint64_t seed, double max_rotation_deg) {
    return pose_to_array(start_pose_at_distance(poses_from_array(truth, nullptr)[0],
                                                points3d_from_array(surface, "surface_points"), centre, distance_mm,
                                                seed, {max_rotation_deg}));
  }, arg("truth"), arg("surface_points"), arg("centre"), arg("distance_mm"), arg("seed") = 1,
     arg("max_rotation_deg") = 45.0, "a pose whose mean surface distance from truth is distance_mm (deterministic in seed)");
}

}  // namespace fluoro::py_bind
