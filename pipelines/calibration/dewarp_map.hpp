#pragma once
// A fitted distortion map (MAP.json): distorted pixels <-> corrected pixels, where the corrected
// image is the plate's ideal pinhole image (a square lattice of pitch pitch_px, axes along the image's).
#include <Eigen/Core>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "engine/image.hpp"
#include "pipelines/calibration/polynomial_map.hpp"

namespace fluoro {

// polynomial: a global least-squares polynomial (the default); bilinear: the seed's local bilinear
// interpolation over the lattice cells.
enum class DewarpModel { polynomial, bilinear };
DewarpModel parse_dewarp_model(const std::string& name);  // InputError on an unknown name
std::string dewarp_model_name(DewarpModel model);

// Where the lattice lies in the corrected image: node (i, j) at origin_px + pitch_px (i, j). `covered`
// marks, over [i_min, i_max] x [j_min, j_max], the nodes the map vouches for (see docs/calibration.md).
struct DewarpLattice {
  Eigen::Vector2d origin_px{0, 0};
  double pitch_px = 1;
  int i_min = 0, i_max = 0, j_min = 0, j_max = 0;
  std::vector<uint8_t> covered;  // row-major, (j - j_min) * (i_max - i_min + 1) + (i - i_min)
  bool is_covered(int i, int j) const;
};

// The map: corrected -> distorted ("inverse", what remapping an image needs) is the model itself;
// distorted -> corrected is its Newton inverse started from a fitted forward polynomial.
class DewarpMap {
 public:
  // bilinear_nodes_px: distorted positions of nodes [i_min-1, i_max+1] x [j_min-1, j_max+1], row-major
  // by j (needed only for the bilinear model but always kept so MAP.json can switch models).
  DewarpMap(DewarpModel model, int width, int height, DewarpLattice lattice, PolynomialMap2 inverse,
            PolynomialMap2 forward_guess, std::vector<Eigen::Vector2d> bilinear_nodes_px);

  // Reads MAP.json; InputError naming the path for a missing file, bad JSON, a failed fit or a
  // malformed map.
  static DewarpMap read(const std::string& path);
  static DewarpMap from_json(const nlohmann::json& j, const std::string& what);
  // The map's own keys (kind, model, size, pitch_px, lattice, polynomial, bilinear).
  nlohmann::json to_json() const;

  // The corrected image's size (the grid image's), its lattice pitch, the model and the lattice frame.
  int width() const { return width_; }
  int height() const { return height_; }
  double pitch_px() const { return lattice_.pitch_px; }
  DewarpModel model() const { return model_; }
  const DewarpLattice& lattice() const { return lattice_; }

  // Distorted pixel -> corrected pixel; nullopt outside the map's field of view.
  std::optional<Eigen::Vector2d> correct_point(const Eigen::Vector2d& distorted) const;
  // Corrected pixel -> distorted pixel; nullopt outside the field of view.
  std::optional<Eigen::Vector2d> distort_point(const Eigen::Vector2d& corrected) const;
  bool in_field_of_view(const Eigen::Vector2d& corrected) const;

  // The corrected image: same size and type (any depth, 1-4 channels), 0 outside the field of view,
  // bilinear resampling through remap tables computed once per map (the first call pays).
  cv::Mat correct_image(const cv::Mat& distorted) const;
  Image correct_image(const Image& distorted) const;

 private:
  Eigen::Vector2d to_distorted(const Eigen::Vector2d& corrected) const;  // the model, no FOV check
  Eigen::Vector2d bilinear(const Eigen::Vector2d& corrected) const;
  const std::pair<cv::Mat, cv::Mat>& remap_tables() const;

  DewarpModel model_;
  int width_, height_;
  DewarpLattice lattice_;
  PolynomialMap2 inverse_, forward_guess_;
  std::vector<Eigen::Vector2d> nodes_;
  struct Cache;
  std::shared_ptr<Cache> cache_;
};

}  // namespace fluoro
