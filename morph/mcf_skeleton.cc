#include "morph/mcf_skeleton.h"

// First: CGAL's containers here allocate from an arena while a skeleton is made (the
// skeletonization orders its edge collapses by the addresses of its halfedges).
// clang-format off
#include "geometry/cgal_arena.h"
// clang-format on

#include <CGAL/Mean_curvature_flow_skeletonization.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/extract_mean_curvature_flow_skeleton.h>

#include "io/error.h"

namespace vb::morph {

SkeletonGraph MeanCurvatureFlowSkeleton(const geometry::TriangleMesh& mesh) {
  // Made before, and so destroyed after, every CGAL object below.
  geometry::CgalArena arena;
  const geometry::CgalArenaScope scope(&arena);
  using Kernel = CGAL::Simple_cartesian<double>;
  using Point = Kernel::Point_3;
  using SurfaceMesh = CGAL::Surface_mesh<Point>;
  using Skeletonization = CGAL::Mean_curvature_flow_skeletonization<SurfaceMesh>;

  SurfaceMesh sm;
  std::vector<SurfaceMesh::Vertex_index> handles;
  handles.reserve(static_cast<std::size_t>(mesh.num_vertices()));
  for (int i = 0; i < mesh.num_vertices(); ++i)
    handles.push_back(sm.add_vertex(Point(mesh.V(0, i), mesh.V(1, i), mesh.V(2, i))));
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const auto face = sm.add_face(handles[static_cast<std::size_t>(mesh.F(0, f))],
                                  handles[static_cast<std::size_t>(mesh.F(1, f))],
                                  handles[static_cast<std::size_t>(mesh.F(2, f))]);
    if (face == SurfaceMesh::null_face()) {
      throw InputError("skeleton: face " + std::to_string(f) + " makes the template non-manifold");
    }
  }
  if (!CGAL::is_closed(sm)) throw InputError("skeleton: the template mesh is not closed");

  Skeletonization::Skeleton skeleton;
  CGAL::extract_mean_curvature_flow_skeleton(sm, skeleton);

  SkeletonGraph out;
  const auto n = boost::num_vertices(skeleton);
  out.nodes.resize(3, static_cast<Eigen::Index>(n));
  out.support.resize(n);
  for (const auto v : CGAL::make_range(boost::vertices(skeleton))) {
    const Point& p = skeleton[v].point;
    out.nodes.col(static_cast<Eigen::Index>(v)) = Eigen::Vector3d(p.x(), p.y(), p.z());
    for (const auto mv : skeleton[v].vertices) out.support[v].push_back(static_cast<int>(mv.idx()));
  }
  for (const auto e : CGAL::make_range(boost::edges(skeleton))) {
    out.edges.push_back({static_cast<int>(boost::source(e, skeleton)),
                         static_cast<int>(boost::target(e, skeleton))});
  }
  return out;
}

}  // namespace vb::morph
