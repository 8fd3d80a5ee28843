#pragma once
// Closest points on a triangle mesh through Embree's BVH point query (rtcPointQuery): the nearest
// surface point, its triangle's normal and the distance, for one point or a batch in parallel.
#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "engine/triangle_mesh.hpp"

namespace fluoro {

// The surface point nearest a query: where it is, the unit normal of its triangle (sign follows
// the triangle's winding), the distance in mm and the triangle's index in the input mesh.
struct SurfacePoint {
  Eigen::Vector3d point;
  Eigen::Vector3d normal;
  double distance = 0;
  int triangle = -1;
};

// A spatial index over a mesh's triangles (Embree BVH in float for the search, the distances in
// double). Immutable after construction; queries are thread-safe.
class MeshClosestPoint {
 public:
  // Zero-area triangles are left out (their points lie on their neighbours' edges). Throws
  // InputError naming `what` when no triangle has an area.
  MeshClosestPoint(const TriangleMesh& mesh, const std::string& what);
  ~MeshClosestPoint();
  MeshClosestPoint(const MeshClosestPoint&) = delete;
  MeshClosestPoint& operator=(const MeshClosestPoint&) = delete;

  SurfacePoint closest(const Eigen::Vector3d& query) const;
  // The closest point of every query, computed in parallel (oneTBB).
  std::vector<SurfacePoint> closest(const std::vector<Eigen::Vector3d>& queries) const;
  // The same, exact too, faster when each query has a point known to lie on the surface near it
  // (e.g. its closest point before a small move): the search starts within that distance.
  // `near` is ignored unless it has one entry per query.
  std::vector<SurfacePoint> closest(const std::vector<Eigen::Vector3d>& queries,
                                    const std::vector<SurfacePoint>& near) const;

  size_t triangle_count() const;

  struct Impl;  // Embree scene and the triangles in double (public for the query callback)

 private:
  // The closest point, searching first within `radius` (which must be at least the distance).
  SurfacePoint closest_within(const Eigen::Vector3d& query, double radius) const;

  std::unique_ptr<Impl> impl_;
};

// The point of triangle (a, b, c) nearest p (Ericson, Real-Time Collision Detection 5.1.5), exact
// in double, also for degenerate triangles.
Eigen::Vector3d closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                          const Eigen::Vector3d& b, const Eigen::Vector3d& c);

}  // namespace fluoro
