#include "geometry/mesh_measures.h"

#include <Eigen/Geometry>

namespace vb::geometry {

Eigen::Matrix3Xd VertexNormals(const TriangleMesh& mesh) {
  Eigen::Matrix3Xd N = Eigen::Matrix3Xd::Zero(3, mesh.num_vertices());
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = mesh.V.col(mesh.F(0, f));
    const Eigen::Vector3d area_vector =
        (mesh.V.col(mesh.F(1, f)) - a).cross(mesh.V.col(mesh.F(2, f)) - a);
    for (int k = 0; k < 3; ++k) N.col(mesh.F(k, f)) += area_vector;
  }
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    const double norm = N.col(i).norm();
    if (norm > 0.0) N.col(i) /= norm;
  }
  return N;
}

Eigen::VectorXd CurvatureSums(const TriangleMesh& mesh, const Eigen::Matrix3Xd& N) {
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(mesh.num_vertices());
  Eigen::VectorXi edges = Eigen::VectorXi::Zero(mesh.num_vertices());
  for (int f = 0; f < mesh.num_faces(); ++f) {
    for (int c = 0; c < 3; ++c) {
      const int a = mesh.F(c, f);
      const int b = mesh.F((c + 1) % 3, f);
      const Eigen::Vector3d d = mesh.V.col(b) - mesh.V.col(a);
      const double squared_length = d.squaredNorm();
      if (!(squared_length > 0.0)) continue;
      const double along = (N.col(b) - N.col(a)).dot(d) / squared_length;
      sum[a] += along;
      sum[b] += along;
      ++edges[a];
      ++edges[b];
    }
  }
  for (int i = 0; i < mesh.num_vertices(); ++i)
    if (edges[i] > 0) sum[i] *= 2.0 / edges[i];
  return sum;
}

double SignedVolume(const TriangleMesh& mesh) {
  if (mesh.num_vertices() == 0) return 0.0;
  // Relative to a vertex of the mesh, to keep the sum well conditioned far from the origin.
  const Eigen::Vector3d o = mesh.V.col(0);
  double six_volume = 0.0;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = mesh.V.col(mesh.F(0, f)) - o;
    const Eigen::Vector3d b = mesh.V.col(mesh.F(1, f)) - o;
    const Eigen::Vector3d c = mesh.V.col(mesh.F(2, f)) - o;
    six_volume += a.dot(b.cross(c));
  }
  return six_volume / 6.0;
}

double SurfaceArea(const TriangleMesh& mesh) {
  double twice_area = 0.0;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = mesh.V.col(mesh.F(0, f));
    twice_area += (mesh.V.col(mesh.F(1, f)) - a).cross(mesh.V.col(mesh.F(2, f)) - a).norm();
  }
  return twice_area / 2.0;
}

Eigen::VectorXd VertexAreas(const TriangleMesh& mesh) {
  Eigen::VectorXd area = Eigen::VectorXd::Zero(mesh.num_vertices());
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = mesh.V.col(mesh.F(0, f));
    const double third =
        (mesh.V.col(mesh.F(1, f)) - a).cross(mesh.V.col(mesh.F(2, f)) - a).norm() / 6.0;
    for (int k = 0; k < 3; ++k) area[mesh.F(k, f)] += third;
  }
  return area;
}

double BoundingBoxDiagonal(const Eigen::Ref<const Eigen::Matrix3Xd>& P) {
  if (P.cols() == 0) return 0.0;
  return (P.rowwise().maxCoeff() - P.rowwise().minCoeff()).norm();
}

}  // namespace vb::geometry
