#include "pipelines/registration/bone_mesh.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <unordered_map>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
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
  // Each vertex's neighbours in one array (offsets per vertex), in the order of the edges, so
  // that every mean sums them in the same order.
  const size_t nv = mesh.vertices.size();
  std::vector<uint32_t> first(nv + 1, 0);
  for (const auto& e : mesh.edges) {
    ++first[size_t(e.a) + 1];
    ++first[size_t(e.b) + 1];
  }
  for (size_t i = 0; i < nv; ++i) first[i + 1] += first[i];
  std::vector<int> neighbours(first[nv]);
  std::vector<uint32_t> fill(first.begin(), first.end() - 1);
  for (const auto& e : mesh.edges) {
    neighbours[fill[size_t(e.a)]++] = e.b;
    neighbours[fill[size_t(e.b)]++] = e.a;
  }
  std::vector<Eigen::Vector3d> moved(nv);
  const auto pass = [&](double factor) {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nv, 4096), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) {
        if (first[i] == first[i + 1]) {
          moved[i] = mesh.vertices[i];
          continue;
        }
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (uint32_t n = first[i]; n != first[i + 1]; ++n) mean += mesh.vertices[size_t(neighbours[n])];
        mean /= double(first[i + 1] - first[i]);
        moved[i] = mesh.vertices[i] + factor * (mean - mesh.vertices[i]);
      }
    });
    mesh.vertices.swap(moved);
  };
  for (int i = 0; i < iterations; ++i) {
    pass(0.5);
    pass(-0.53);
  }
}

// The mask of inside(i, j, k) on a grid coarsened by `f` (a coarse voxel is inside when more
// than half of its voxels are), padded by one empty voxel so that its surface is closed. Throws
// InputError (`what`, `empty_reason`) when no coarse voxel is inside.
template <class Inside>
MaskImage::Pointer coarse_mask(const VolumeGeometry& g, int f, Inside inside, const std::string& what, const char* empty_reason) {
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
  return image;
}

// For each configuration of a cube's 8 corners (bit x + 2y + 4z set when corner (x, y, z) is
// inside), ceil(e / 3), e the cube's edges whose two corners differ. Marching cubes puts a vertex
// on each such edge and each of those vertices in at least one triangle of that cube (ITK's
// tables also use a vertex at the cube's centre in some cases), three vertices a triangle: at
// least this many triangles in the cube. tests/registration_test.cpp checks it against ITK for
// all 256 configurations.
constexpr std::array<uint8_t, 256> least_triangles_table() {
  std::array<uint8_t, 256> t{};
  for (int config = 0; config < 256; ++config) {
    int crossing = 0;
    for (int corner = 0; corner < 8; ++corner)
      for (int bit = 1; bit < 8; bit <<= 1)
        if (!(corner & bit)) crossing += ((config >> corner) & 1) != ((config >> (corner | bit)) & 1);
    t[size_t(config)] = uint8_t((crossing + 2) / 3);
  }
  return t;
}

// A lower bound of the triangles marching cubes makes of `image` (least_triangles_table), known
// for a fraction of the mesh's cost: on the 3 mm pelvis CT about 0.01 s against 0.38 s for a
// mesh of 148,000 triangles that the triangle limit then discards.
size_t least_triangles(const MaskImage& image) {
  static constexpr std::array<uint8_t, 256> table = least_triangles_table();
  const auto size = image.GetLargestPossibleRegion().GetSize();
  const size_t nx = size[0], ny = size[1], nz = size[2];
  const unsigned char* const p = image.GetBufferPointer();
  return tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, nz - 1), size_t(0),
      [&](const tbb::blocked_range<size_t>& r, size_t count) {
        for (size_t k = r.begin(); k != r.end(); ++k)
          for (size_t j = 0; j + 1 < ny; ++j) {
            // Rows (j, k), (j + 1, k), (j, k + 1), (j + 1, k + 1); mask values are 0 or 1.
            const unsigned char* a = p + (k * ny + j) * nx;
            const unsigned char* b = a + nx;
            const unsigned char* c = a + nx * ny;
            const unsigned char* d = c + nx;
            for (size_t i = 0; i + 1 < nx; ++i)
              count += table[size_t(a[i] | a[i + 1] << 1 | b[i] << 2 | b[i + 1] << 3 | c[i] << 4 | c[i + 1] << 5 |
                                    d[i] << 6 | d[i + 1] << 7)];
          }
        return count;
      },
      std::plus<size_t>());
}

// ITK's surface of a coarse mask (coarsened by `f` from `g`) as welded vertices in the CT frame
// and the triangles that keep three distinct corners.
BoneMesh welded_triangles(const ItkMesh& mesh, const VolumeGeometry& g, int f) {
  BoneMesh out;
  // ITK's points are in the padded coarse grid's index space (unit spacing, zero origin); weld
  // coincident points so edges are shared, and map them to the CT frame.
  struct KeyHash {
    size_t operator()(const std::array<long long, 3>& k) const {
      return std::hash<long long>()(k[0] * 73856093LL ^ k[1] * 19349663LL ^ k[2] * 83492791LL);
    }
  };
  std::unordered_map<std::array<long long, 3>, int, KeyHash> welded;
  welded.reserve(mesh.GetNumberOfPoints());
  std::vector<int> remap(mesh.GetNumberOfPoints(), -1);
  for (auto it = mesh.GetPoints()->Begin(); it != mesh.GetPoints()->End(); ++it) {
    const auto& p = it.Value();
    const std::array<long long, 3> key = {std::llround(p[0] * 1024), std::llround(p[1] * 1024), std::llround(p[2] * 1024)};
    auto [slot, fresh] = welded.try_emplace(key, int(out.vertices.size()));
    if (fresh) {
      const Eigen::Vector3d coarse(p[0] - 1, p[1] - 1, p[2] - 1);
      out.vertices.push_back(g.index_to_physical(coarse * f + Eigen::Vector3d::Constant(0.5 * (f - 1))));
    }
    remap[it.Index()] = slot->second;
  }
  for (auto it = mesh.GetCells()->Begin(); it != mesh.GetCells()->End(); ++it) {
    const auto* cell = it.Value();
    if (cell->GetNumberOfPoints() != 3) continue;
    std::array<int, 3> t;
    int i = 0;
    for (auto id = cell->PointIdsBegin(); id != cell->PointIdsEnd(); ++id) t[i++] = remap[*id];
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
    out.triangles.push_back(t);
  }
  return out;
}

// The manifold edges of welded triangles, then the smoothing.
BoneMesh with_edges_smoothed(BoneMesh out, int iterations, const std::string& what, const char* empty_reason) {
  // Edge -> the opposite vertices of its triangles; keep the manifold ones (exactly two
  // triangles), in the order of their vertices (a, b), each edge's opposite vertices in the order
  // of the triangles. One sorted array rather than a map of lists: a mesh has 10^5 edges.
  struct HalfEdge {
    unsigned long long key;  // a << 32 | b, a < b
    int opposite;
  };
  std::vector<HalfEdge> half_edges;
  half_edges.reserve(out.triangles.size() * 3);
  for (const auto& t : out.triangles)
    for (int e = 0; e < 3; ++e) {
      const int a = std::min(t[e], t[(e + 1) % 3]), b = std::max(t[e], t[(e + 1) % 3]);
      half_edges.push_back({(static_cast<unsigned long long>(a) << 32) | unsigned(b), t[(e + 2) % 3]});
    }
  std::stable_sort(half_edges.begin(), half_edges.end(), [](const HalfEdge& x, const HalfEdge& y) { return x.key < y.key; });
  for (size_t i = 0; i < half_edges.size();) {
    size_t j = i + 1;
    while (j < half_edges.size() && half_edges[j].key == half_edges[i].key) ++j;
    if (j - i == 2)
      out.edges.push_back({int(half_edges[i].key >> 32), int(half_edges[i].key & 0xffffffffu), half_edges[i].opposite,
                           half_edges[i + 1].opposite});
    i = j;
  }
  if (out.edges.empty()) throw_input_error(what, empty_reason);
  taubin_smooth(out, iterations);
  return out;
}

// ITK's marching cubes of a coarse mask.
ItkMesh::Pointer marching_cubes(const MaskImage::Pointer& mask) {
  auto source = itk::BinaryMask3DMeshSource<MaskImage, ItkMesh>::New();
  source->SetInput(mask);
  source->SetObjectValue(1);
  source->Update();
  ItkMesh::Pointer mesh = source->GetOutput();
  mesh->DisconnectPipeline();
  return mesh;
}

// The mesh at the coarsening max_voxel_mm asks for, coarsened further until it has at most
// max_triangles (or the grid is down to a few voxels). A finer level is given up as soon as its
// size is known: before marching cubes when least_triangles already exceeds the limit (a lower
// bound of ITK's triangles, and so of the welded ones: welding can only drop triangles), else on
// the welded triangles' count, before the edges and the smoothing.
template <class Inside>
BoneMesh coarsest_mesh(const VolumeGeometry& g, const BoneMeshParams& params, Inside inside, const std::string& what,
                       const char* empty_reason) {
  for (int f = coarsening(g, params.max_voxel_mm);; ++f) {
    const bool last = g.size.minCoeff() / (f + 1) < 8;
    const MaskImage::Pointer mask = coarse_mask(g, f, inside, what, empty_reason);
    if (!last && least_triangles(*mask) > params.max_triangles) continue;
    BoneMesh welded = welded_triangles(*marching_cubes(mask), g, f);
    if (!last && welded.triangles.size() > params.max_triangles) continue;
    return with_edges_smoothed(std::move(welded), params.smoothing_iterations, what, empty_reason);
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

MarchingCubesCount marching_cubes_count(const Volume& mask) {
  const MaskImage::Pointer padded =
      coarse_mask(mask.geometry, 1, [&](int i, int j, int k) { return mask.at(i, j, k) != 0.0f; }, "mask", "the mask is empty");
  const ItkMesh::Pointer mesh = marching_cubes(padded);
  size_t triangles = 0;
  for (auto it = mesh->GetCells()->Begin(); it != mesh->GetCells()->End(); ++it) triangles += it.Value()->GetNumberOfPoints() == 3;
  return {least_triangles(*padded), triangles};
}

BoneMesh bone_mesh_from_mask(const Volume& mask, const BoneMeshParams& params, const std::string& what) {
  return coarsest_mesh(mask.geometry, params, [&](int i, int j, int k) { return mask.at(i, j, k) != 0.0f; }, what,
                       "the mask is empty");
}

}  // namespace fluoro
