#include "pipelines/registration/bone_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <functional>

#include <itkBinaryMask3DMeshSource.h>
#include <itkImage.h>
#include <itkMesh.h>

#include "engine/error.hpp"

namespace fluoro {
namespace {

using MaskImage = itk::Image<unsigned char, 3>;
using ItkMesh = itk::Mesh<double, 3>;

// The coarsening factor that brings the smallest spacing up to max_voxel_mm (at least 1).
int coarsening(const VolumeGeometry& g, double max_voxel_mm) {
  const double s = g.spacing.minCoeff();
  return std::max(1, int(std::floor(max_voxel_mm / s + 1e-9)));
}

// Taubin's lambda|mu smoothing (1995): removes the binary mask's voxel staircase, whose every
// step would otherwise fold the surface and add spurious apparent-contour edges, without the
// shrinking of plain Laplacian smoothing.
void taubin_smooth(BoneMesh& mesh, int iterations) {
  std::vector<std::vector<int>> neighbours(mesh.vertices.size());
  for (const auto& e : mesh.edges) {
    neighbours[size_t(e.a)].push_back(e.b);
    neighbours[size_t(e.b)].push_back(e.a);
  }
  std::vector<Eigen::Vector3d> moved(mesh.vertices.size());
  const auto pass = [&](double factor) {
    for (size_t i = 0; i < mesh.vertices.size(); ++i) {
      if (neighbours[i].empty()) {
        moved[i] = mesh.vertices[i];
        continue;
      }
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (int n : neighbours[i]) mean += mesh.vertices[size_t(n)];
      mean /= double(neighbours[i].size());
      moved[i] = mesh.vertices[i] + factor * (mean - mesh.vertices[i]);
    }
    mesh.vertices.swap(moved);
  };
  for (int i = 0; i < iterations; ++i) {
    pass(0.5);
    pass(-0.53);
  }
}

// Builds the mesh of inside(i, j, k) on a grid coarsened by `f` (a coarse voxel is inside when
// more than half of its voxels are), padded by one empty voxel so the surface is closed.
template <class Inside>
BoneMesh mesh_of(const VolumeGeometry& g, int f, int iterations, Inside inside, const std::string& what, const char* empty_reason) {
  const Eigen::Vector3i n = (g.size + Eigen::Vector3i::Constant(f - 1)) / f;
  auto image = MaskImage::New();
  MaskImage::RegionType region;
  region.SetSize({size_t(n.x() + 2), size_t(n.y() + 2), size_t(n.z() + 2)});
  image->SetRegions(region);
  image->Allocate();
  image->FillBuffer(0);
  // Coarse slices in parallel, each writing its own pixels of the padded image.
  unsigned char* const pixels = image->GetBufferPointer();
  const size_t row = size_t(n.x()) + 2, slice = row * (size_t(n.y()) + 2);
  const size_t inside_count = tbb::parallel_reduce(
      tbb::blocked_range<int>(0, n.z()), size_t(0),
      [&](const tbb::blocked_range<int>& r, size_t count) {
        std::vector<int> in(size_t(n.x())), total(size_t(n.x()));
        for (int k = r.begin(); k != r.end(); ++k)
          for (int j = 0; j < n.y(); ++j) {
            std::fill(in.begin(), in.end(), 0);
            std::fill(total.begin(), total.end(), 0);
            for (int c = k * f; c < std::min(k * f + f, g.size.z()); ++c)
              for (int b = j * f; b < std::min(j * f + f, g.size.y()); ++b)
                for (int i = 0; i < n.x(); ++i)
                  for (int a = i * f; a < std::min(i * f + f, g.size.x()); ++a) {
                    in[size_t(i)] += inside(a, b, c);
                    ++total[size_t(i)];
                  }
            unsigned char* out = pixels + size_t(k + 1) * slice + size_t(j + 1) * row + 1;
            for (int i = 0; i < n.x(); ++i)
              if (2 * in[size_t(i)] > total[size_t(i)]) {
                out[i] = 1;
                ++count;
              }
          }
        return count;
      },
      std::plus<size_t>());
  if (inside_count == 0) throw_input_error(what, empty_reason);

  auto source = itk::BinaryMask3DMeshSource<MaskImage, ItkMesh>::New();
  source->SetInput(image);
  source->SetObjectValue(1);
  source->Update();
  const ItkMesh* mesh = source->GetOutput();

  BoneMesh out;
  // ITK's points are in the padded coarse grid's index space (unit spacing, zero origin); weld
  // coincident points so edges are shared, and map them to the CT frame.
  std::map<std::array<long long, 3>, int> welded;
  std::vector<int> remap(mesh->GetNumberOfPoints(), -1);
  for (auto it = mesh->GetPoints()->Begin(); it != mesh->GetPoints()->End(); ++it) {
    const auto& p = it.Value();
    const std::array<long long, 3> key = {std::llround(p[0] * 1024), std::llround(p[1] * 1024), std::llround(p[2] * 1024)};
    auto [slot, fresh] = welded.try_emplace(key, int(out.vertices.size()));
    if (fresh) {
      const Eigen::Vector3d coarse(p[0] - 1, p[1] - 1, p[2] - 1);
      out.vertices.push_back(g.index_to_physical(coarse * f + Eigen::Vector3d::Constant(0.5 * (f - 1))));
    }
    remap[it.Index()] = slot->second;
  }
  for (auto it = mesh->GetCells()->Begin(); it != mesh->GetCells()->End(); ++it) {
    const auto* cell = it.Value();
    if (cell->GetNumberOfPoints() != 3) continue;
    std::array<int, 3> t;
    int i = 0;
    for (auto id = cell->PointIdsBegin(); id != cell->PointIdsEnd(); ++id) t[i++] = remap[*id];
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
    out.triangles.push_back(t);
  }
  // Edge -> the opposite vertices of its triangles; keep the manifold ones.
  std::unordered_map<unsigned long long, std::vector<int>> opposite;
  opposite.reserve(out.triangles.size() * 2);
  for (const auto& t : out.triangles)
    for (int e = 0; e < 3; ++e) {
      const int a = std::min(t[e], t[(e + 1) % 3]), b = std::max(t[e], t[(e + 1) % 3]);
      opposite[(static_cast<unsigned long long>(a) << 32) | unsigned(b)].push_back(t[(e + 2) % 3]);
    }
  out.edges.reserve(opposite.size());
  for (const auto& [key, opp] : opposite)
    if (opp.size() == 2) out.edges.push_back({int(key >> 32), int(key & 0xffffffffu), opp[0], opp[1]});
  // Deterministic order (the hash map's is not).
  std::sort(out.edges.begin(), out.edges.end(),
            [](const BoneMesh::Edge& x, const BoneMesh::Edge& y) { return std::tie(x.a, x.b) < std::tie(y.a, y.b); });
  if (out.edges.empty()) throw_input_error(what, empty_reason);
  taubin_smooth(out, iterations);
  return out;
}

// The mesh at the coarsening max_voxel_mm asks for, coarsened further until it has at most
// max_triangles (or the grid is down to a few voxels).
template <class Inside>
BoneMesh coarsest_mesh(const VolumeGeometry& g, const BoneMeshParams& params, Inside inside, const std::string& what,
                       const char* empty_reason) {
  for (int f = coarsening(g, params.max_voxel_mm);; ++f) {
    BoneMesh m = mesh_of(g, f, params.smoothing_iterations, inside, what, empty_reason);
    if (m.triangles.size() <= params.max_triangles || g.size.minCoeff() / (f + 1) < 8) return m;
  }
}

}  // namespace

Eigen::Vector3d BoneMesh::centroid() const {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& v : vertices) c += v;
  return vertices.empty() ? c : Eigen::Vector3d(c / double(vertices.size()));
}

BoneMesh bone_mesh_from_iso(const Volume& hu, double iso_hu, const BoneMeshParams& params, const std::string& what) {
  const float iso = float(iso_hu);
  const std::string reason = "no bone: no voxel reaches the iso-value " + std::to_string(int(std::lround(iso_hu))) + " HU";
  return coarsest_mesh(hu.geometry, params, [&](int i, int j, int k) { return hu.at(i, j, k) >= iso; }, what,
                       reason.c_str());
}

BoneMesh bone_mesh_from_mask(const Volume& mask, const BoneMeshParams& params, const std::string& what) {
  return coarsest_mesh(mask.geometry, params, [&](int i, int j, int k) { return mask.at(i, j, k) != 0.0f; }, what,
                       "the mask is empty");
}

}  // namespace fluoro
