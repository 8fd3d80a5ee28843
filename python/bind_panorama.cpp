// The panorama (docs/python.md): frames in (corrected with a dewarp map first when one is given,
// as `fluoro panorama --dewarp` does), the PANO.json document `fluoro panorama` writes (as a dict,
// without inputs and timings), the composed image and, on request, the `--overlay` picture out;
// `fluoro measure` on it; and the
// generated panorama sets of datasets/panorama_scene.hpp with their truth, to test it on.
#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>

#include <opencv2/core.hpp>

#include "datasets/panorama_scene.hpp"
#include "engine/error.hpp"
#include "engine/image_mat.hpp"
#include "engine/json_io.hpp"
#include "pipelines/panorama/panorama.hpp"
#include "pipelines/calibration/dewarp_map.hpp"
#include "pipelines/panorama/panorama_document.hpp"
#include "pipelines/panorama/panorama_overlay.hpp"
#include "python/common.hpp"

namespace fluoro::py_bind {

using py::arg;

namespace {

nlohmann::json from_python(const py::handle& o) {
  return nlohmann::json::parse(py::module_::import("json").attr("dumps")(o).cast<std::string>());
}

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

// The overlay's CV_8UC3 BGR picture as an (H, W, 3) uint8 RGB array, as `--overlay` writes its PNG.
py::array_t<uint8_t> overlay_to_rgb(const cv::Mat& bgr) {
  py::array_t<uint8_t> rgb({py::ssize_t(bgr.rows), py::ssize_t(bgr.cols), py::ssize_t(3)});
  auto r = rgb.mutable_unchecked<3>();
  for (int y = 0; y < bgr.rows; ++y)
    for (int x = 0; x < bgr.cols; ++x) {
      const cv::Vec3b c = bgr.at<cv::Vec3b>(y, x);
      for (int k = 0; k < 3; ++k) r(y, x, k) = c[2 - k];
    }
  return rgb;
}

// MAP.json as a path or as the dict `fit_dewarp` returns; `name` is what the messages and the
// document call it.
DewarpMap dewarp_from_object(const py::handle& dewarp, std::string& name) {
  if (py::isinstance<py::str>(dewarp)) {
    name = dewarp.cast<std::string>();
    return DewarpMap::read(name);
  }
  name = "dewarp";
  if (!py::isinstance<py::dict>(dewarp)) throw_input_error(name, "expected a MAP.json path or the dict fit_dewarp returns");
  return DewarpMap::from_json(from_python(dewarp), name);
}

}  // namespace

void bind_panorama(py::module_& m) {
  m.def("panorama", [](const py::sequence& frames, const py::handle& contours, double graduation_mm,
                       const std::string& blend, bool allow_partial, std::optional<std::vector<std::string>> names,
                       const py::handle& dewarp, bool overlay) {
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
    // The distortion correction first, as `fluoro panorama --dewarp`: every frame goes through the
    // map before the ruler is looked for.
    std::optional<DewarpMap> map;
    std::string map_name;
    if (!dewarp.is_none()) map = dewarp_from_object(dewarp, map_name);
    std::vector<FloatArray> arrays;
    std::vector<Image> corrected;
    std::vector<cv::Mat> mats;
    for (size_t i = 0; i < n; ++i) {
      arrays.push_back(FloatArray::ensure(frames[i]));
      const FloatArray& a = arrays.back();
      if (!a || a.ndim() != 2) throw_input_error(files[i], "expected an (H, W) array of numbers");
      if (a.shape(0) != arrays[0].shape(0) || a.shape(1) != arrays[0].shape(1))
        throw_input_error(files[i], "its size " + std::to_string(a.shape(1)) + " x " + std::to_string(a.shape(0)) +
                                        " differs from the first frame's " + std::to_string(arrays[0].shape(1)) +
                                        " x " + std::to_string(arrays[0].shape(0)));
      if (map && (a.shape(1) != map->width() || a.shape(0) != map->height()))
        throw_input_error(map_name, "the map is for " + std::to_string(map->width()) + " x " +
                                        std::to_string(map->height()) + " images, the frames are " +
                                        std::to_string(a.shape(1)) + " x " + std::to_string(a.shape(0)));
    }
    if (map) {
      py::gil_scoped_release release;
      corrected.resize(n);
      for (size_t i = 0; i < n; ++i) {
        Image frame(int(arrays[i].shape(1)), int(arrays[i].shape(0)));
        std::copy(arrays[i].data(), arrays[i].data() + arrays[i].size(), frame.pixels.begin());
        corrected[i] = map->correct_image(frame);
      }
    }
    for (size_t i = 0; i < n; ++i)
      mats.push_back(map ? mat_view(corrected[i])
                         : mat_over(arrays[i]));
    std::optional<PlaneContours> plane;
    if (!contours.is_none()) {
      const bool path = py::isinstance<py::str>(contours);
      // C.json's points are traced on the frames as acquired: the map takes them to the corrected frames.
      const std::function<std::optional<Eigen::Vector2d>(const Eigen::Vector2d&)> to_frames =
          map ? std::function<std::optional<Eigen::Vector2d>(const Eigen::Vector2d&)>(
                    [&map](const Eigen::Vector2d& p) { return map->correct_point(p); })
              : [](const Eigen::Vector2d& p) { return std::optional<Eigen::Vector2d>(p); };
      plane = plane_contours_from_json(path ? read_json(contours.cast<std::string>()) : from_python(contours),
                                       path ? contours.cast<std::string>() : "contours", int(n), mats[0].cols,
                                       mats[0].rows, to_frames);
    }
    PanoramaOptions options;
    options.graduation_mm = graduation_mm;
    options.blend = rule;
    nlohmann::json doc;
    cv::Mat image, picture;
    {
      py::gil_scoped_release release;
      const Panorama p = align_panorama(mats, options, plane);
      doc = panorama_document(p, files, graduation_mm, blend, map_name, plane.has_value(), allow_partial);
      if (doc["status"] == "ok") {
        image = compose_panorama(mats, p, rule);
        if (overlay) picture = panorama_overlay(image, mats, p);
      }
    }
    py::object result_image = image.empty() ? py::object(py::none()) : py::object(mat_to_array(std::move(image)));
    if (!overlay) return py::make_tuple(json_to_python(doc), result_image);
    py::object result_overlay = picture.empty() ? py::object(py::none()) : py::object(overlay_to_rgb(picture));
    return py::make_tuple(json_to_python(doc), result_image, result_overlay);
  }, arg("frames"), arg("contours") = py::none(), arg("graduation_mm") = 5.0, arg("blend") = "max",
     arg("allow_partial") = false, arg("names") = py::none(), arg("dewarp") = py::none(), arg("overlay") = false,
     "(PANO.json document as a dict, the (H, W) float32 panorama or None when it failed[, the overlay]) from the "
     "frames as acquired; dewarp: MAP.json (path or fit_dewarp's dict) correcting every frame and the contours first, "
     "as `fluoro panorama --dewarp`; contours: C.json as a path or a dict; names: the frames' names in the document; "
     "overlay=True adds the `--overlay` picture as an (H, W, 3) uint8 RGB array (None when it failed)");

  m.def("dewarp_image", [](const py::handle& image, const py::handle& dewarp) {
    std::string name;
    const DewarpMap map = dewarp_from_object(dewarp, name);
    const Image im = array_to_image(image, "image");
    if (im.width != map.width() || im.height != map.height())
      throw_input_error("image", "is " + std::to_string(im.width) + "x" + std::to_string(im.height) +
                                     ", the map is for " + std::to_string(map.width()) + "x" +
                                     std::to_string(map.height()));
    Image out;
    {
      py::gil_scoped_release release;
      out = map.correct_image(im);
    }
    return image_to_array(std::move(out));
  }, arg("image"), arg("dewarp"),
     "`fluoro dewarp apply --in` for a float image: the (H, W) float32 image corrected by the map (MAP.json path or "
     "fit_dewarp's dict), 0 outside its field of view");
  m.def("dewarp_points", [](const py::handle& points, const py::handle& dewarp) {
    std::string name;
    const DewarpMap map = dewarp_from_object(dewarp, name);
    const DoubleArray q = DoubleArray::ensure(points);
    if (!q || q.ndim() != 2 || q.shape(1) != 2) throw_input_error("points", "expected an (N, 2) array of pixels (u, v)");
    py::array_t<double> out({q.shape(0), py::ssize_t(2)});
    auto r = out.mutable_unchecked<2>();
    const auto in = q.unchecked<2>();
    for (py::ssize_t i = 0; i < q.shape(0); ++i) {
      const std::optional<Eigen::Vector2d> c = map.correct_point({in(i, 0), in(i, 1)});
      r(i, 0) = c ? c->x() : std::nan("");
      r(i, 1) = c ? c->y() : std::nan("");
    }
    return out;
  }, arg("points"), arg("dewarp"),
     "`fluoro dewarp apply --points`: distorted pixels (N, 2) to corrected ones; NaN outside the map's field of view "
     "(null in the program's point list)");

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
    d["uncertainty_mm"] = r.uncertainty_mm ? py::object(py::float_(*r.uncertainty_mm)) : py::object(py::none());
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
    d["contours"] = json_to_python(c);
    d["bone_plane_mm"] = s.bone_plane_mm;
    d["ruler_plane_mm"] = s.ruler_plane_mm;
    return d;
  }, arg("pixels") = 512, arg("frames") = 6, arg("ruler_offset_mm") = -50.0, arg("occluders") = true,
     arg("seed") = 1u,
     "a generated long-bone set with its truth: images (16-bit values as float32), rotation_deg, true_length_mm, "
     "landmark_px (frames, 2, 2), contours (C.json), bone_plane_mm, ruler_plane_mm");
}

}  // namespace fluoro::py_bind
