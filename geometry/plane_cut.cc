#include "geometry/plane_cut.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <tuple>

#include "io/error.h"

namespace vb::geometry {
namespace {

// The crossing of edge (k, k+1) of a face, as a surface point of that face.
SurfacePoint CrossingOnEdge(int face, int k, double d_from, double d_to) {
  const double t = d_from / (d_from - d_to);
  SurfacePoint p;
  p.face = face;
  p.barycentric.setZero();
  p.barycentric[k] = 1.0 - t;
  p.barycentric[(k + 1) % 3] = t;
  return p;
}

struct EdgeKey {
  int lo, hi, face;
  bool operator<(const EdgeKey& o) const {
    return std::tie(lo, hi, face) < std::tie(o.lo, o.hi, o.face);
  }
};

}  // namespace

std::vector<SectionLoop> PlaneSection(const TriangleMesh& mesh, const Plane& plane) {
  const int nf = mesh.num_faces();
  std::vector<double> d(static_cast<std::size_t>(mesh.num_vertices()));
  for (int i = 0; i < mesh.num_vertices(); ++i)
    d[static_cast<std::size_t>(i)] = plane.SignedDistance(mesh.V.col(i));
  auto positive = [&d](int v) { return d[static_cast<std::size_t>(v)] >= 0.0; };

  // For each crossing face: the local index of its entry edge (negative to positive) and of
  // its exit edge (positive to negative), walking the face's boundary in its own order.
  std::vector<std::array<int, 2>> crossing(static_cast<std::size_t>(nf), {-1, -1});
  std::vector<EdgeKey> entries;
  for (int f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      const int a = mesh.F(k, f), b = mesh.F((k + 1) % 3, f);
      if (positive(a) == positive(b)) continue;
      if (!positive(a)) {
        crossing[static_cast<std::size_t>(f)][0] = k;
        entries.push_back({std::min(a, b), std::max(a, b), f});
      } else {
        crossing[static_cast<std::size_t>(f)][1] = k;
      }
    }
  }
  std::sort(entries.begin(), entries.end());
  auto next_face = [&](int f) {
    const int k = crossing[static_cast<std::size_t>(f)][1];
    const int a = mesh.F(k, f), b = mesh.F((k + 1) % 3, f);
    const int lo = std::min(a, b), hi = std::max(a, b);
    auto it = std::lower_bound(entries.begin(), entries.end(), EdgeKey{lo, hi, -1});
    for (; it != entries.end() && it->lo == lo && it->hi == hi; ++it) {
      if (it->face != f) return it->face;
    }
    return -1;
  };
  std::vector<int> successor(static_cast<std::size_t>(nf), -1);
  std::vector<bool> has_predecessor(static_cast<std::size_t>(nf), false);
  for (int f = 0; f < nf; ++f) {
    if (crossing[static_cast<std::size_t>(f)][0] < 0) continue;
    successor[static_cast<std::size_t>(f)] = next_face(f);
    if (successor[static_cast<std::size_t>(f)] >= 0)
      has_predecessor[static_cast<std::size_t>(successor[static_cast<std::size_t>(f)])] = true;
  }

  std::vector<SectionLoop> loops;
  std::vector<bool> visited(static_cast<std::size_t>(nf), false);
  auto walk = [&](int start) {
    SectionLoop loop;
    int f = start;
    while (f >= 0 && !visited[static_cast<std::size_t>(f)]) {
      visited[static_cast<std::size_t>(f)] = true;
      const int k = crossing[static_cast<std::size_t>(f)][0];
      loop.points.push_back(CrossingOnEdge(f, k, d[static_cast<std::size_t>(mesh.F(k, f))],
                                           d[static_cast<std::size_t>(mesh.F((k + 1) % 3, f))]));
      f = successor[static_cast<std::size_t>(f)];
    }
    loop.closed = f == start;
    loops.push_back(std::move(loop));
  };
  // Open chains first (only on meshes with boundary), from their first face.
  for (int f = 0; f < nf; ++f) {
    if (crossing[static_cast<std::size_t>(f)][0] >= 0 &&
        !has_predecessor[static_cast<std::size_t>(f)] && !visited[static_cast<std::size_t>(f)])
      walk(f);
  }
  for (int f = 0; f < nf; ++f) {
    if (crossing[static_cast<std::size_t>(f)][0] >= 0 && !visited[static_cast<std::size_t>(f)])
      walk(f);
  }
  return loops;
}

namespace {

struct HalfSpace {
  Eigen::Vector3d normal;  // keep normal.dot(x - point) >= 0
  Eigen::Vector3d point;
  Eigen::Vector3d cap_origin;  // a point on the plane used to close the cut face
};

struct Corner {
  Eigen::Vector3d p;
  int tag;  // what the edge from this corner to the next lies on: -1 surface, else half-space
};

void Clip(const HalfSpace& h, int tag, std::vector<Corner>* polygon, std::vector<Corner>* scratch) {
  scratch->clear();
  const std::size_t n = polygon->size();
  for (std::size_t i = 0; i < n; ++i) {
    const Corner& a = (*polygon)[i];
    const Corner& b = (*polygon)[(i + 1) % n];
    const double da = h.normal.dot(a.p - h.point);
    const double db = h.normal.dot(b.p - h.point);
    const bool in_a = da >= 0.0, in_b = db >= 0.0;
    if (in_a) scratch->push_back(a);
    if (in_a != in_b) {
      const Eigen::Vector3d x = a.p + (da / (da - db)) * (b.p - a.p);
      scratch->push_back({x, in_a ? tag : a.tag});
    }
  }
  std::swap(*polygon, *scratch);
}

}  // namespace

std::vector<PartMeasure> MeasureParts(const TriangleMesh& mesh, std::span<const Plane> cuts) {
  const std::size_t num_parts = cuts.size() + 1;
  std::vector<PartMeasure> parts(num_parts);
  if (mesh.num_vertices() == 0) return parts;
  const Eigen::Vector3d o = mesh.V.col(0);
  std::vector<Corner> polygon, scratch;
  for (std::size_t part = 0; part < num_parts; ++part) {
    std::vector<HalfSpace> bounds;
    if (part > 0)
      bounds.push_back({-cuts[part - 1].normal, cuts[part - 1].point, cuts[part - 1].point});
    if (part < cuts.size())
      bounds.push_back({cuts[part].normal, cuts[part].point, cuts[part].point});
    if (bounds.size() == 2) {
      // Close both cut faces from one point on both planes, so the stretch of cut-face
      // boundary along the planes' common line (which no triangle produces) adds nothing.
      Eigen::Matrix<double, 2, 3> A;
      A.row(0) = bounds[0].normal.transpose();
      A.row(1) = bounds[1].normal.transpose();
      const Eigen::Vector2d c(bounds[0].normal.dot(bounds[0].point),
                              bounds[1].normal.dot(bounds[1].point));
      const Eigen::Matrix2d G = A * A.transpose();
      if (std::abs(G.determinant()) > 1e-12) {
        const Eigen::Vector3d x = o + A.transpose() * G.ldlt().solve(c - A * o);
        bounds[0].cap_origin = x;
        bounds[1].cap_origin = x;
      }
    }
    double six_volume = 0.0;
    double twice_area = 0.0;
    for (int f = 0; f < mesh.num_faces(); ++f) {
      polygon.clear();
      for (int k = 0; k < 3; ++k) polygon.push_back({mesh.V.col(mesh.F(k, f)), -1});
      for (std::size_t b = 0; b < bounds.size() && !polygon.empty(); ++b)
        Clip(bounds[b], static_cast<int>(b), &polygon, &scratch);
      if (polygon.size() < 3) continue;
      for (std::size_t i = 1; i + 1 < polygon.size(); ++i) {
        const Eigen::Vector3d a = polygon[0].p - o, b = polygon[i].p - o, c = polygon[i + 1].p - o;
        six_volume += a.dot(b.cross(c));
        twice_area += (b - a).cross(c - a).norm();
      }
      for (std::size_t i = 0; i < polygon.size(); ++i) {
        const int tag = polygon[i].tag;
        if (tag < 0) continue;
        // The cut face runs the shared edge the other way round.
        const Eigen::Vector3d a = bounds[static_cast<std::size_t>(tag)].cap_origin - o;
        const Eigen::Vector3d b = polygon[(i + 1) % polygon.size()].p - o;
        const Eigen::Vector3d c = polygon[i].p - o;
        six_volume += a.dot(b.cross(c));
      }
    }
    parts[part].volume = six_volume / 6.0;
    parts[part].area = twice_area / 2.0;
  }
  return parts;
}

}  // namespace vb::geometry
