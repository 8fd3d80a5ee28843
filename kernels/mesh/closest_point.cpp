#include "kernels/mesh/closest_point.hpp"

#include <Eigen/Geometry>
#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "engine/error.hpp"

namespace fluoro {
namespace {

Eigen::Vector3d closest_point_on_segment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double len2 = ab.squaredNorm();
  if (!(len2 > 0)) return a;
  return a + std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) * ab;
}

}  // namespace

Eigen::Vector3d closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                          const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // Voronoi regions of the vertices, then of the edges, then the face.
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double sum = va + vb + vc;
  if (!(sum > 0)) {
    // A degenerate (zero-area) triangle the tests above did not settle: the nearest of its edges.
    Eigen::Vector3d best = closest_point_on_segment(p, a, b);
    const Eigen::Vector3d on_bc = closest_point_on_segment(p, b, c), on_ca = closest_point_on_segment(p, c, a);
    if ((on_bc - p).squaredNorm() < (best - p).squaredNorm()) best = on_bc;
    if ((on_ca - p).squaredNorm() < (best - p).squaredNorm()) best = on_ca;
    return best;
  }
  return a + (vb / sum) * ab + (vc / sum) * ac;
}

struct MeshClosestPoint::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<Eigen::Vector3d> a, b, c, normal;  // per kept triangle, double
  std::vector<int> source_index;                  // kept triangle -> input triangle

  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

namespace {

// The running best of one query: Embree calls back for every triangle whose bounds meet the
// query sphere; the exact distance is computed in double and the sphere shrinks to it.
struct QueryState {
  const MeshClosestPoint::Impl* mesh;
  Eigen::Vector3d p;
  double best_d2 = std::numeric_limits<double>::infinity();
  Eigen::Vector3d best_point = Eigen::Vector3d::Zero();
  unsigned best_triangle = RTC_INVALID_GEOMETRY_ID;
};

bool closest_point_callback(RTCPointQueryFunctionArguments* args) {
  auto* state = static_cast<QueryState*>(args->userPtr);
  const unsigned t = args->primID;
  const Eigen::Vector3d q = closest_point_on_triangle(state->p, state->mesh->a[t], state->mesh->b[t], state->mesh->c[t]);
  const double d2 = (q - state->p).squaredNorm();
  if (d2 >= state->best_d2) return false;
  state->best_d2 = d2;
  state->best_point = q;
  state->best_triangle = t;
  // The float radius rounded up, so that rounding never culls a triangle at the same distance.
  args->query->radius = std::nextafter(static_cast<float>(std::sqrt(d2)), std::numeric_limits<float>::infinity());
  return true;
}

}  // namespace

MeshClosestPoint::MeshClosestPoint(const TriangleMesh& mesh, const std::string& what) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  double scale2 = 0;
  for (const auto& v : mesh.vertices) scale2 = std::max(scale2, v.squaredNorm());
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    const Eigen::Vector3d& a = mesh.vertices[size_t(tri[0])];
    const Eigen::Vector3d& b = mesh.vertices[size_t(tri[1])];
    const Eigen::Vector3d& c = mesh.vertices[size_t(tri[2])];
    const Eigen::Vector3d n = (b - a).cross(c - a);
    if (!(n.norm() > 1e-14 * std::max(1.0, scale2))) continue;
    m.a.push_back(a);
    m.b.push_back(b);
    m.c.push_back(c);
    m.normal.push_back(n.normalized());
    m.source_index.push_back(int(t));
  }
  if (m.a.empty()) throw_input_error(what, "every triangle of the mesh has zero area");

  m.device = rtcNewDevice(nullptr);
  if (!m.device) throw std::runtime_error("Embree: cannot create a device (error " + std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
  m.scene = rtcNewScene(m.device);
  // Medium, not high: a command builds the index once for one ICP, and high quality's spatial
  // splits cost 4x the build time for about 25 % faster queries (bench/calibration_bench.cpp).
  rtcSetSceneBuildQuality(m.scene, RTC_BUILD_QUALITY_MEDIUM);
  RTCGeometry geometry = rtcNewGeometry(m.device, RTC_GEOMETRY_TYPE_TRIANGLE);
  const size_t n = m.a.size();
  // Unshared float vertices, three per triangle: the BVH only needs bounds, and this keeps the
  // kept-triangle numbering simple.
  auto* vertices = static_cast<float*>(
      rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 3 * n));
  auto* indices = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), n));
  if (!vertices || !indices) {
    rtcReleaseGeometry(geometry);
    throw std::runtime_error("Embree: cannot allocate the mesh buffers");
  }
  for (size_t t = 0; t < n; ++t) {
    const Eigen::Vector3d* corners[3] = {&m.a[t], &m.b[t], &m.c[t]};
    for (int k = 0; k < 3; ++k) {
      for (int i = 0; i < 3; ++i) vertices[9 * t + 3 * k + i] = static_cast<float>((*corners[k])[i]);
      indices[3 * t + k] = unsigned(3 * t + k);
    }
  }
  rtcSetGeometryPointQueryFunction(geometry, closest_point_callback);
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(m.scene, geometry);
  rtcReleaseGeometry(geometry);
  rtcCommitScene(m.scene);
  if (const RTCError e = rtcGetDeviceError(m.device); e != RTC_ERROR_NONE)
    throw std::runtime_error("Embree: building the BVH failed (error " + std::to_string(int(e)) + ")");
}

MeshClosestPoint::~MeshClosestPoint() = default;

size_t MeshClosestPoint::triangle_count() const { return impl_->a.size(); }

namespace {

// One Embree point query within `radius`; false when no triangle is that near.
bool query_within(const MeshClosestPoint::Impl& mesh, RTCScene scene, QueryState& state, float radius) {
  RTCPointQuery q;
  q.x = static_cast<float>(state.p.x());
  q.y = static_cast<float>(state.p.y());
  q.z = static_cast<float>(state.p.z());
  q.time = 0;
  q.radius = radius;
  RTCPointQueryContext context;
  rtcInitPointQueryContext(&context);
  rtcPointQuery(scene, &q, &context, nullptr, &state);
  return state.best_triangle != RTC_INVALID_GEOMETRY_ID;
}

}  // namespace

SurfacePoint MeshClosestPoint::closest(const Eigen::Vector3d& query) const {
  return closest_within(query, std::numeric_limits<double>::infinity());
}

SurfacePoint MeshClosestPoint::closest_within(const Eigen::Vector3d& query, double radius) const {
  QueryState state{impl_.get(), query};
  // The float BVH's bounds are rounded: a margin keeps a triangle at exactly `radius` in the search.
  const double margin = 1e-5 * (query.norm() + radius) + 1e-6;
  bool found = std::isfinite(radius) && query_within(*impl_, impl_->scene, state, float(radius + margin));
  if (!found) found = query_within(*impl_, impl_->scene, state, std::numeric_limits<float>::infinity());
  if (!found) throw std::runtime_error("Embree: a closest-point query found no triangle");
  SurfacePoint s;
  s.point = state.best_point;
  s.normal = impl_->normal[state.best_triangle];
  s.distance = std::sqrt(state.best_d2);
  s.triangle = impl_->source_index[state.best_triangle];
  return s;
}

std::vector<SurfacePoint> MeshClosestPoint::closest(const std::vector<Eigen::Vector3d>& queries,
                                                    const std::vector<SurfacePoint>& near) const {
  if (near.size() != queries.size()) return closest(queries);
  std::vector<SurfacePoint> out(queries.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, queries.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) out[i] = closest_within(queries[i], (queries[i] - near[i].point).norm());
  });
  return out;
}

std::vector<SurfacePoint> MeshClosestPoint::closest(const std::vector<Eigen::Vector3d>& queries) const {
  std::vector<SurfacePoint> out(queries.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, queries.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) out[i] = closest(queries[i]);
  });
  return out;
}

}  // namespace fluoro
