#pragma once
// Distance from a point to the nearest triangle of an Embree scene (rtcPointQuery), for tests that
// check recorded points lie on the scene's surfaces. Reads the triangle buffers the way
// scene/scene.cpp creates them (RTC_FORMAT_FLOAT3 vertices and UINT3 indices, tightly packed).
#include <algorithm>
#include <cmath>
#include <limits>

#include <embree3/rtcore.h>
#include <Eigen/Core>

namespace lidartwin::test {

// Ericson, Real-Time Collision Detection, 5.1.5: closest point on triangle abc to p.
inline Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                           const Eigen::Vector3d& c) {
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
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

struct NearestQuery {
  RTCScene scene;
  Eigen::Vector3d point;  // the query in double precision
  double best = std::numeric_limits<double>::infinity();
};

inline bool shrink_to_triangle(RTCPointQueryFunctionArguments* args) {
  auto& nearest = *static_cast<NearestQuery*>(args->userPtr);
  RTCGeometry geometry = rtcGetGeometry(nearest.scene, args->geomID);
  const auto* v = static_cast<const float*>(rtcGetGeometryBufferData(geometry, RTC_BUFFER_TYPE_VERTEX, 0));
  const auto* i = static_cast<const unsigned*>(rtcGetGeometryBufferData(geometry, RTC_BUFFER_TYPE_INDEX, 0));
  const unsigned* tri = i + 3 * args->primID;
  // In double: with 100 m triangles, float barycentrics are off by millimetres.
  const auto vertex = [&](unsigned k) {
    return Eigen::Vector3d(static_cast<double>(v[3 * k]), static_cast<double>(v[3 * k + 1]),
                           static_cast<double>(v[3 * k + 2]));
  };
  const Eigen::Vector3d& p = nearest.point;
  const double distance = (closest_on_triangle(p, vertex(tri[0]), vertex(tri[1]), vertex(tri[2])) - p).norm();
  if (distance >= nearest.best) return false;
  nearest.best = distance;
  args->query->radius = static_cast<float>(distance) * 1.0001f + 1e-6f;  // never below the double best
  return true;
}

// Distance to the nearest surface, or +inf if none lies within search_radius_m.
inline double distance_to_surface(RTCScene scene, const Eigen::Vector3d& p, float search_radius_m = 0.05f) {
  alignas(16) RTCPointQuery query;
  query.x = static_cast<float>(p.x());
  query.y = static_cast<float>(p.y());
  query.z = static_cast<float>(p.z());
  query.time = 0.0f;
  query.radius = search_radius_m;
  RTCPointQueryContext context;
  rtcInitPointQueryContext(&context);
  NearestQuery nearest{scene, p};
  rtcPointQuery(scene, &query, &context, shrink_to_triangle, &nearest);
  return nearest.best;
}

}  // namespace lidartwin::test
