#pragma once
// Hole detection in a dewarp-grid X-ray: bright, roughly round blobs on the plate found by a
// top-hat and connected components (OpenCV), centred to sub-pixel by an intensity-weighted centroid.
#include <Eigen/Core>
#include <vector>

#include "engine/image.hpp"

namespace fluoro {

// One detected blob: its sub-pixel centre, thresholded area and integrated top-hat contrast.
struct HoleBlob {
  Eigen::Vector2d centre_px{0, 0};
  double area_px = 0;
  double mass = 0;  // sum of the top-hat over the centroid window: a cut or covered hole has less
};

// Every plausible hole, plus what the fit needs to judge coverage: the illuminated area (the
// intensifier's field of view, black outside) and the typical blob diameter.
struct HoleDetection {
  std::vector<HoleBlob> blobs;
  double illuminated_area_px = 0;
  double typical_diameter_px = 0;
};

// Levels do not matter (a top-hat against the local plate level, a threshold from the image's own
// statistics); blobs far from the typical hole's size or shape (dust, cut holes) are left out.
HoleDetection detect_holes(const Image& image);

}  // namespace fluoro
