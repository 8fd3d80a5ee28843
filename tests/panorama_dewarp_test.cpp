// Panoramas through a dewarp (docs/panorama.md "Dewarp"): frames bent by an image intensifier's
// distortion (a generated grid scene's, 6 px at the edge of 512^2), corrected with a map fitted to
// that scene's grid image; the bone length against the truth, in-process and through the command.
#include <gtest/gtest.h>

#include <sstream>

#include "datasets/dewarp_grid.hpp"
#include "datasets/panorama_scene.hpp"
#include "engine/image_io.hpp"
#include "engine/image_mat.hpp"
#include "engine/json_io.hpp"
#include "pipelines/calibration/dewarp_fit.hpp"
#include "pipelines/panorama/panorama.hpp"
#include "tests/cli_fixture.hpp"

namespace fluoro {
namespace {

Image to_float(const ImageU16& im) {
  Image out;
  out.width = im.width, out.height = im.height;
  out.pixels.assign(im.pixels.begin(), im.pixels.end());
  return out;
}

cv::Mat to_mat(const Image& im) { return mat_view(im).clone(); }

// The set of the former failure: seed 2, ruler 50 mm nearer the source than the bone, 6 frames of
// 512^2 with k-wires and a clamp; the grid scene of seed 1 bends them.
struct DistortedSet {
  PanoramaScene scene;
  DewarpScene grid;
  std::vector<Image> distorted;
};

const DistortedSet& distorted_set() {
  static const DistortedSet d = [] {
    DistortedSet s;
    PanoramaSceneParams p;
    p.ruler_offset_mm = -50;
    p.seed = 2;
    s.scene = make_panorama_scene(p);
    DewarpSceneOptions o;
    o.size = 512;
    s.grid = make_dewarp_scene(o);
    for (const auto& im : s.scene.images) s.distorted.push_back(distort_image(to_float(im), s.grid.distortion));
    return s;
  }();
  return d;
}

// Where the truth's landmark k appears in frame f as acquired (bent by the distortion).
Eigen::Vector2d distorted_landmark(const DistortedSet& d, int f, int k) {
  return d.grid.distortion.distort(project_in_frame(d.scene, f, d.scene.landmarks[k]));
}

// The former failure: after the dewarp the last frame's 50 mm mark is cut by the field's edge, so
// only the 10 mm marks fix the graduation count to its predecessor, and the anatomy must choose
// between candidates 10 mm apart. The decisive pairs' anatomy had locked on two depths (the bone,
// and the k-wires 65 mm nearer the source); their median was the wires', and the anatomy
// correlated best 10 mm off at that scale: a length two graduations short, reported with full
// confidence. Now the other marks of that frame (each residue but the cut mark's read twice at the
// 10 mm length) give the 50 mm residue, every depth the decisive pairs saw is tried, and a count
// that only the 10 mm marks fix must lead the others clearly (docs/panorama.md "Dewarp").
TEST(PanoramaDewarp, TwiceResampledFramesGiveTheBoneLength) {
  const DistortedSet& d = distorted_set();
  const DewarpFit fit = fit_dewarp(d.grid.image, d.grid.grid);
  ASSERT_TRUE(fit.ok) << fit.reason;
  const DewarpMap& map = *fit.map;
  std::vector<cv::Mat> frames;
  for (const Image& im : d.distorted) frames.push_back(map.correct_image(to_mat(im)));
  PlaneContours c;
  c.first = d.scene.contour_first_frame;
  for (int k = 0; k < 2; ++k)
    for (const auto& q : d.scene.contour[k]) {
      const auto corrected = map.correct_point(d.grid.distortion.distort(q));
      if (corrected) c.polylines[k].push_back(*corrected);
    }
  const Panorama p = align_panorama(frames, {}, c);
  ASSERT_TRUE(p.failure.empty()) << p.failure;
  ASSERT_EQ(p.plane, "contours");
  Eigen::Vector2d q[2];
  for (int k = 0; k < 2; ++k) {
    const int f = k == 0 ? 0 : int(frames.size()) - 1;
    const auto px = map.correct_point(distorted_landmark(d, f, k));
    ASSERT_TRUE(px.has_value());
    q[k] = (p.frames[size_t(f)].H_panorama_frame * Eigen::Vector3d(px->x(), px->y(), 1)).head<2>();
  }
  const double length = (q[1] - q[0]).norm() * p.mm_per_pixel;
  // A graduation off would be 5 mm (1.3 %); the goal is 0.5 %.
  EXPECT_NEAR(length, d.scene.true_length_mm, 0.005 * d.scene.true_length_mm);
}

class PanoramaDewarpCli : public test::CliTest {};

TEST_F(PanoramaDewarpCli, DistortedFramesAndAFittedMapGiveTheBoneLength) {
  const DistortedSet& d = distorted_set();
  save_dewarp_scene(d.grid, path("grid.png"), path("grid.json"));
  ASSERT_EQ(run("dewarp fit --image " + path("grid.png") + " --grid " + path("grid.json") + " --out " + path("map.json")).code, 0);
  std::string images;
  for (size_t i = 0; i < d.distorted.size(); ++i) {
    const std::string f = path("f" + std::to_string(i) + ".png");
    std::vector<uint16_t> px(d.distorted[i].pixels.size());
    for (size_t k = 0; k < px.size(); ++k) px[k] = uint16_t(std::clamp(std::lround(d.distorted[i].pixels[k]), 0L, 65535L));
    write_png_u16(px, d.distorted[i].width, d.distorted[i].height, f);
    images += " " + f;
  }
  // C.json traced on the frames as acquired (FORMATS.md): the distorted contour.
  nlohmann::json c;
  c["frames"] = {d.scene.contour_first_frame, d.scene.contour_first_frame + 1};
  c["polylines"] = nlohmann::json::array();
  for (int k = 0; k < 2; ++k) {
    nlohmann::json line = nlohmann::json::array();
    for (const auto& q : d.scene.contour[k]) {
      const Eigen::Vector2d b = d.grid.distortion.distort(q);
      line.push_back({b.x(), b.y()});
    }
    c["polylines"].push_back(line);
  }
  write_json(c, path("C.json"));
  const test::CliResult r = run("panorama --images" + images + " --dewarp " + path("map.json") + " --plane-contours " +
                                path("C.json") + " --out " + path("pano.png") + " --report " + path("pano.json"));
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json j = read_json(path("pano.json"));
  EXPECT_EQ(j["plane"], "contours");
  EXPECT_EQ(j["dewarp"], path("map.json"));
  // H maps corrected pixels: the landmarks as acquired go through the same map first.
  const DewarpMap map = DewarpMap::read(path("map.json"));
  Eigen::Vector2d q[2];
  for (int k = 0; k < 2; ++k) {
    const int f = k == 0 ? 0 : int(d.distorted.size()) - 1;
    Eigen::Matrix3d H;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) H(a, b) = j["frames"][size_t(f)]["H_panorama_frame"][size_t(a)][size_t(b)];
    const auto px = map.correct_point(distorted_landmark(d, f, k));
    ASSERT_TRUE(px.has_value());
    q[k] = (H * Eigen::Vector3d(px->x(), px->y(), 1)).head<2>();
  }
  std::ostringstream pts;
  pts.precision(10);
  pts << q[0].x() << "," << q[0].y() << "," << q[1].x() << "," << q[1].y();
  const test::CliResult m = run("measure --report " + path("pano.json") + " --points " + pts.str() + " --out " + path("m.json"));
  ASSERT_EQ(m.code, 0) << m.err;
  EXPECT_NEAR(read_json(path("m.json"))["distance_mm"].get<double>(), d.scene.true_length_mm, 0.005 * d.scene.true_length_mm);

  // A map made for another image size: exit 2 naming the map, nothing written.
  DewarpSceneOptions other;
  other.size = 256;
  save_dewarp_scene(make_dewarp_scene(other), path("grid256.png"), path("grid256.json"));
  ASSERT_EQ(run("dewarp fit --image " + path("grid256.png") + " --grid " + path("grid256.json") + " --out " + path("map256.json")).code, 0);
  const test::CliResult bad = run("panorama --images" + images + " --dewarp " + path("map256.json") + " --out " +
                                  path("pano2.png") + " --report " + path("pano2.json"));
  EXPECT_EQ(bad.code, 2) << bad.err;
  EXPECT_NE(bad.err.find("map256.json"), std::string::npos) << bad.err;
  EXPECT_FALSE(std::filesystem::exists(path("pano2.png")));
  EXPECT_FALSE(std::filesystem::exists(path("pano2.json")));
}

}  // namespace
}  // namespace fluoro
