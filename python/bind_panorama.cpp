// The panorama (docs/python.md): frames in, the PANO.json document `fluoro panorama` writes (as a
// dict, without inputs and timings) and the composed image out; `fluoro measure` on it; and the
// generated panorama sets of datasets/panorama_scene.hpp with their truth, to test it on.
#include <algorithm>
#include <cmath>
#include <optional>

#include <opencv2/core.hpp>

#include "datasets/panorama_scene.hpp"
#include "engine/error.hpp"
#include "engine/json_io.hpp"
#include "pipelines/panorama/panorama.hpp"
#include "pipelines/panorama/panorama_document.hpp"
#include "python/common.hpp"

namespace fluoro::py_bind {

using py::arg;

namespace {

nlohmann::json from_python(const py::handle& o) {
  return nlohmann::json::parse(py::module_::import("json").attr("dumps")(o).cast<std::string>());
}
py::object to_python(const nlohmann::json& j) { return py::module_::import("json").attr("loads")(j.dump()); }

// A float32 (H, W) cv::Mat over the array's buffer: no copy when the array is already float32 and
// C-contiguous (forcecast copies otherwise). The array must outlive the Mat.
cv::Mat mat_over(const FloatArray& a) {
  return cv::Mat(int(a.shape(0)), int(a.shape(1)), CV_32F, const_cast<float*>(a.data()));
}

// The composed CV_32F image as an (H, W) array owning the Mat's buffer (no copy).
py::array_t<float> mat_to_array(cv::Mat&& m) {
  auto* owner = new cv::Mat(std::move(m));
  py::capsule free_when_done(owner, [](void* p) { delete static_cast<cv::Mat*>(p); });
  return py::array_t<float>({owner->rows, owner->cols}, {py::ssize_t(owner->step[0]), py::ssize_t(sizeof(float))},
                            owner->ptr<float>(), free_when_done);
}

}  // namespace

void bind_panorama(py::module_& m) {
  m.def("panorama", [](const py::sequence& frames, const py::handle& contours, double graduation_mm,
                       const std::string& blend, bool allow_partial, std::optional<std::vector<std::string>> names) {
    const size_t n = py::len(frames);
    if (n < 2) throw_input_error("frames", "a panorama needs at least 2 frames");
    if (!(graduation_mm > 0) || !std::isfinite(graduation_mm))
      throw_input_error("graduation_mm", "must be a positive number of millimetres");
    const PanoramaBlend rule = parse_panorama_blend(blend, "blend");
    std::vector<std::string> files(n);
    for (size_t i = 0; i < n; ++i) files[i] = "frames[" + std::to_string(i) + "]";
    if (names) {
      if (names->size() != n)
        throw_input_error("names", std::to_string(names->size()) + " names for " + std::to_string(n) + " frames");
      files = *names;
    }
    std::vector<FloatArray> arrays;
    std::vector<cv::Mat> mats;
    for (size_t i = 0; i < n; ++i) {
      arrays.push_back(FloatArray::ensure(frames[i]));
      const FloatArray& a = arrays.back();
      if (!a || a.ndim() != 2) throw_input_error(files[i], "expected an (H, W) array of numbers");
      if (a.shape(0) != arrays[0].shape(0) || a.shape(1) != arrays[0].shape(1))
        throw_input_error(files[i], "its size " + std::to_string(a.shape(1)) + " x " + std::to_string(a.shape(0)) +
                                        " differs from the first frame's " + std::to_string(arrays[0].shape(1)) +
                                        " x " + std::to_string(arrays[0].shape(0)));
      mats.push_back(mat_over(a));
    }
    std::optional<PlaneContours> plane;
    if (!contours.is_none()) {
      const bool path = py::isinstance<py::str>(contours);
      const auto identity = [](const Eigen::Vector2d& p) { return std::optional<Eigen::Vector2d>(p); };
      plane = plane_contours_from_json(path ? read_json(contours.cast<std::string>()) : from_python(contours),
                                       path ? contours.cast<std::string>() : "contours", int(n), mats[0].cols,
                                       mats[0].rows, identity);
    }
    PanoramaOptions options;
    options.graduation_mm = graduation_mm;
    options.blend = rule;
    nlohmann::json doc;
    cv::Mat image;
    {
      py::gil_scoped_release release;
      const Panorama p = align_panorama(mats, options, plane);
      doc = panorama_document(p, files, graduation_mm, blend, "", plane.has_value(), allow_partial);
      if (doc["status"] == "ok") image = compose_panorama(mats, p, rule);
    }
    if (image.empty()) return py::make_tuple(to_python(doc), py::none());
    return py::make_tuple(to_python(doc), mat_to_array(std::move(image)));
  }, arg("frames"), arg("contours") = py::none(), arg("graduation_mm") = 5.0, arg("blend") = "max",
     arg("allow_partial") = false, arg("names") = py::none(),
     "(PANO.json document as a dict, the (H, W) float32 panorama or None when it failed) from distortion-corrected "
     "frames; contours: C.json as a path or a dict; names: the frames' names in the document");

  m.def("measure", [](const py::handle& report, const py::handle& points) {
    const bool path = py::isinstance<py::str>(report);
    const nlohmann::json doc = path ? read_json(report.cast<std::string>()) : from_python(report);
    const std::string what = path ? report.cast<std::string>() : "report";
    check_panorama_report(doc, what);  // the report's problems before the points', as the command
    const DoubleArray q = DoubleArray::ensure(points);
    if (!q || q.size() != 4 || !(q.ndim() == 1 || (q.ndim() == 2 && q.shape(0) == 2)))
      throw_input_error("points", "expected two panorama pixels ((2, 2) or u1, v1, u2, v2)");
    const double* v = q.data();
    const PanoramaDistance r = measure_on_panorama(doc, what, {v[0], v[1]}, {v[2], v[3]}, "points");
    py::dict d;
    d["distance_mm"] = r.distance_mm;
    d["uncertainty_mm"] = r.uncertainty_mm;
    d["distance_px"] = r.distance_px;
    return d;
  }, arg("report"), arg("points"),
     "`fluoro measure`: the distance in mm between two panorama pixels (u, v) in the report's plane (PANO.json path "
     "or the dict `panorama` returns), with its uncertainty");

  m.def("make_panorama_scene", [](int pixels, int frames, double ruler_offset_mm, bool occluders, uint32_t seed) {
    if (pixels < 64) throw_input_error("pixels", "must be at least 64");
    if (frames < 2) throw_input_error("frames", "a panorama needs at least 2 frames");
    PanoramaSceneParams params;
    params.pixels = pixels;
    params.frames = frames;
    params.ruler_offset_mm = ruler_offset_mm;
    params.occluders = occluders;
    params.seed = seed;
    PanoramaScene s;
    {
      py::gil_scoped_release release;
      s = make_panorama_scene(params);
    }
    py::list images;
    for (const ImageU16& im : s.images) {
      Image f(im.width, im.height);
      std::copy(im.pixels.begin(), im.pixels.end(), f.pixels.begin());
      images.append(image_to_array(std::move(f)));
    }
    // Both landmarks' true pixels in every frame: (frames, 2, 2).
    py::array_t<double> landmark_px({py::ssize_t(frames), py::ssize_t(2), py::ssize_t(2)});
    auto r = landmark_px.mutable_unchecked<3>();
    for (int i = 0; i < frames; ++i)
      for (int k = 0; k < 2; ++k) {
        const Eigen::Vector2d q = project_in_frame(s, i, s.landmarks[k]);
        r(i, k, 0) = q.x(), r(i, k, 1) = q.y();
      }
    nlohmann::json c = {{"frames", {s.contour_first_frame, s.contour_first_frame + 1}}, {"polylines", nlohmann::json::array()}};
    for (const auto& line : s.contour) {
      nlohmann::json l = nlohmann::json::array();
      for (const auto& p : line) l.push_back({p.x(), p.y()});
      c["polylines"].push_back(l);
    }
    py::dict d;
    d["images"] = images;
    d["rotation_deg"] = s.rotation_deg;
    d["true_length_mm"] = s.true_length_mm;
    d["landmark_px"] = landmark_px;
    d["contours"] = to_python(c);
    d["bone_plane_mm"] = s.bone_plane_mm;
    d["ruler_plane_mm"] = s.ruler_plane_mm;
    return d;
  }, arg("pixels") = 512, arg("frames") = 6, arg("ruler_offset_mm") = -50.0, arg("occluders") = true,
     arg("seed") = 1u,
     "a generated long-bone set with its truth: images (16-bit values as float32), rotation_deg, true_length_mm, "
     "landmark_px (frames, 2, 2), contours (C.json), bone_plane_mm, ruler_plane_mm");
}

}  // namespace fluoro::py_bind
