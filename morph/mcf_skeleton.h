#pragma once

#include "geometry/triangle_mesh.h"
#include "morph/skeleton_graph.h"

namespace vb::morph {

/// Mean curvature flow skeleton of a closed triangle mesh (Tagliasacchi et al. 2012, through
/// CGAL's Mean_curvature_flow_skeletonization with its default, scale-relative parameters).
/// Each skeleton node's support lists the mesh vertices that collapsed onto it. This is the
/// only translation unit of vb::morph that includes CGAL (about 35 s to compile). The result
/// does not depend on what the process allocated before: CGAL orders its edge collapses by
/// the addresses of its halfedges, which come from a geometry::CgalArena made per call.
/// @throws InputError if the mesh is not a closed 2-manifold CGAL can build.
SkeletonGraph MeanCurvatureFlowSkeleton(const geometry::TriangleMesh& mesh);

}  // namespace vb::morph
