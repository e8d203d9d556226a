// CGAL's alpha wrapping and AABB tree, kept in this one translation unit (CGAL headers are
// slow to compile).
#include "tools/shape_set/surface_wrap.h"

// First: CGAL_ALLOCATOR is one type in every translation unit.
// clang-format off
#include "geometry/cgal_arena.h"
// clang-format on

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/alpha_wrap_3.h>

#include <Eigen/Geometry>
#include <array>
#include <string>

#include "io/error.h"
#include "geometry/mesh_measures.h"

namespace vb::tools {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Triangle = Kernel::Triangle_3;
using SurfaceMesh = CGAL::Surface_mesh<Point>;

Point ToPoint(const Eigen::Vector3d& p) { return Point(p.x(), p.y(), p.z()); }

bool Degenerate(const geometry::TriangleMesh& mesh, int f) {
  const Eigen::Vector3d a = mesh.V.col(mesh.F(0, f));
  const Eigen::Vector3d b = mesh.V.col(mesh.F(1, f));
  const Eigen::Vector3d c = mesh.V.col(mesh.F(2, f));
  const double area2 = (b - a).cross(c - a).norm();
  const double scale = std::max({(b - a).squaredNorm(), (c - a).squaredNorm(), 1e-300});
  return !(area2 > 1e-12 * scale);
}

// The triangle's own frame: first edge, across it in the plane, normal (columns).
Eigen::Matrix3d TriangleFrame(const geometry::TriangleMesh& mesh, int f) {
  const Eigen::Vector3d a = mesh.V.col(mesh.F(0, f));
  const Eigen::Vector3d b = mesh.V.col(mesh.F(1, f));
  const Eigen::Vector3d c = mesh.V.col(mesh.F(2, f));
  Eigen::Matrix3d R;
  R.col(0) = (b - a).normalized();
  R.col(2) = (b - a).cross(c - a).normalized();
  R.col(1) = R.col(2).cross(R.col(0));
  return R;
}

}  // namespace

geometry::TriangleMesh WrapSurface(const geometry::TriangleMesh& soup, const WrapOptions& options) {
  std::vector<Point> points;
  points.reserve(static_cast<std::size_t>(soup.num_vertices()));
  for (Eigen::Index i = 0; i < soup.V.cols(); ++i) points.push_back(ToPoint(soup.V.col(i)));
  std::vector<std::array<std::size_t, 3>> faces;
  for (int f = 0; f < soup.num_faces(); ++f) {
    if (Degenerate(soup, f)) continue;
    faces.push_back({static_cast<std::size_t>(soup.F(0, f)), static_cast<std::size_t>(soup.F(1, f)),
                     static_cast<std::size_t>(soup.F(2, f))});
  }
  if (faces.empty()) throw InputError("wrap: the surface has no non-degenerate triangle");
  const double diagonal = geometry::BoundingBoxDiagonal(soup.V);
  SurfaceMesh wrap;
  CGAL::alpha_wrap_3(points, faces, options.alpha * diagonal, options.offset * diagonal, wrap);
  if (wrap.number_of_faces() == 0) throw InputError("wrap: CGAL's alpha wrap came out empty");

  geometry::TriangleMesh out;
  out.V.resize(3, static_cast<Eigen::Index>(wrap.number_of_vertices()));
  for (SurfaceMesh::Vertex_index v : wrap.vertices()) {
    const Point& p = wrap.point(v);
    out.V.col(static_cast<Eigen::Index>(v.idx())) = Eigen::Vector3d(p.x(), p.y(), p.z());
  }
  out.F.resize(3, static_cast<Eigen::Index>(wrap.number_of_faces()));
  Eigen::Index f = 0;
  for (SurfaceMesh::Face_index face : wrap.faces()) {
    int k = 0;
    for (SurfaceMesh::Vertex_index v : CGAL::vertices_around_face(wrap.halfedge(face), wrap)) {
      if (k < 3) out.F(k, f) = static_cast<int>(v.idx());
      ++k;
    }
    if (k != 3) throw InputError("wrap: CGAL's alpha wrap made a face with " + std::to_string(k) + " corners");
    ++f;
  }
  out.N = geometry::VertexNormals(out);
  return out;
}

std::vector<SurfaceAnchor> AnchorOnSurface(const Eigen::Matrix3Xd& points,
                                           const geometry::TriangleMesh& surface) {
  std::vector<Triangle> triangles;
  std::vector<int> face_of;
  for (int f = 0; f < surface.num_faces(); ++f) {
    if (Degenerate(surface, f)) continue;
    triangles.emplace_back(ToPoint(surface.V.col(surface.F(0, f))),
                           ToPoint(surface.V.col(surface.F(1, f))),
                           ToPoint(surface.V.col(surface.F(2, f))));
    face_of.push_back(f);
  }
  if (triangles.empty()) throw InputError("anchor: the surface has no non-degenerate triangle");
  using Iterator = std::vector<Triangle>::const_iterator;
  using Primitive = CGAL::AABB_triangle_primitive<Kernel, Iterator>;
  using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;
  Tree tree(triangles.cbegin(), triangles.cend());
  tree.accelerate_distance_queries();

  std::vector<SurfaceAnchor> anchors(static_cast<std::size_t>(points.cols()));
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const Eigen::Vector3d q = points.col(i);
    const auto [closest, primitive] = tree.closest_point_and_primitive(ToPoint(q));
    const int f = face_of[static_cast<std::size_t>(primitive - triangles.cbegin())];
    const Eigen::Vector3d p(closest.x(), closest.y(), closest.z());
    const Eigen::Vector3d a = surface.V.col(surface.F(0, f));
    const Eigen::Vector3d b = surface.V.col(surface.F(1, f));
    const Eigen::Vector3d c = surface.V.col(surface.F(2, f));
    // Barycentric coordinates of p (in the triangle's plane) by least squares.
    Eigen::Matrix<double, 3, 2> E;
    E << b - a, c - a;
    const Eigen::Vector2d uv = E.colPivHouseholderQr().solve(p - a);
    SurfaceAnchor& anchor = anchors[static_cast<std::size_t>(i)];
    anchor.face = f;
    anchor.barycentric = Eigen::Vector3d(1.0 - uv.x() - uv.y(), uv.x(), uv.y());
    anchor.offset = TriangleFrame(surface, f).transpose() * (q - p);
  }
  return anchors;
}

Eigen::Matrix3Xd PlaceAnchors(const std::vector<SurfaceAnchor>& anchors,
                              const geometry::TriangleMesh& posed) {
  Eigen::Matrix3Xd out(3, static_cast<Eigen::Index>(anchors.size()));
  for (std::size_t i = 0; i < anchors.size(); ++i) {
    const SurfaceAnchor& anchor = anchors[i];
    const Eigen::Vector3d p = anchor.barycentric(0) * posed.V.col(posed.F(0, anchor.face)) +
                              anchor.barycentric(1) * posed.V.col(posed.F(1, anchor.face)) +
                              anchor.barycentric(2) * posed.V.col(posed.F(2, anchor.face));
    out.col(static_cast<Eigen::Index>(i)) = p + TriangleFrame(posed, anchor.face) * anchor.offset;
  }
  return out;
}

}  // namespace vb::tools
