#include "perception/isotropic_remesh.h"

// First: CGAL_ALLOCATOR is one type in every translation unit.
// clang-format off
#include "geometry/cgal_arena.h"
// clang-format on

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/remesh.h>
#include <CGAL/Surface_mesh.h>

#include <vector>

#include "io/error.h"

namespace vb::perception {

geometry::TriangleMesh IsotropicRemesh(const geometry::TriangleMesh& mesh,
                                       double target_edge_length, int iterations) {
  using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Point = Kernel::Point_3;
  using SurfaceMesh = CGAL::Surface_mesh<Point>;
  VB_DEMAND(target_edge_length > 0.0);

  SurfaceMesh sm;
  std::vector<SurfaceMesh::Vertex_index> handles;
  handles.reserve(static_cast<std::size_t>(mesh.num_vertices()));
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    handles.push_back(sm.add_vertex(Point(mesh.V(0, i), mesh.V(1, i), mesh.V(2, i))));
  }
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const auto face = sm.add_face(handles[static_cast<std::size_t>(mesh.F(0, f))],
                                  handles[static_cast<std::size_t>(mesh.F(1, f))],
                                  handles[static_cast<std::size_t>(mesh.F(2, f))]);
    VB_DEMAND(face != SurfaceMesh::null_face());
  }
  CGAL::Polygon_mesh_processing::isotropic_remeshing(
      faces(sm), target_edge_length, sm,
      CGAL::parameters::number_of_iterations(static_cast<unsigned int>(iterations)));
  sm.collect_garbage();

  geometry::TriangleMesh out;
  out.V.resize(3, static_cast<Eigen::Index>(sm.number_of_vertices()));
  for (const auto v : sm.vertices()) {
    const Point& p = sm.point(v);
    out.V.col(static_cast<Eigen::Index>(v.idx())) = Eigen::Vector3d(p.x(), p.y(), p.z());
  }
  out.F.resize(3, static_cast<Eigen::Index>(sm.number_of_faces()));
  for (const auto f : sm.faces()) {
    int c = 0;
    for (const auto v : CGAL::vertices_around_face(sm.halfedge(f), sm)) {
      out.F(c++, static_cast<Eigen::Index>(f.idx())) = static_cast<int>(v.idx());
    }
  }
  return out;
}

}  // namespace vb::perception
