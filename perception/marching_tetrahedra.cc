#include "perception/marching_tetrahedra.h"

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <unordered_map>
#include <vector>

#include "io/error.h"

namespace vb::perception {
namespace {

// The six tetrahedra of a cube sharing the diagonal from corner 0 to corner 7. Corner index
// bits: 1 = +x, 2 = +y, 4 = +z. The same split in every cube makes neighbouring faces agree.
constexpr int kTets[6][4] = {{0, 1, 3, 7}, {0, 3, 2, 7}, {0, 2, 6, 7},
                             {0, 6, 4, 7}, {0, 4, 5, 7}, {0, 5, 1, 7}};

}  // namespace

geometry::TriangleMesh MarchingTetrahedra(const std::function<double(const Eigen::Vector3d&)>& f,
                                          const Eigen::Vector3d& box_min,
                                          const Eigen::Vector3d& box_max, double h) {
  VB_DEMAND(h > 0.0);
  const Eigen::Vector3d extent = box_max - box_min;
  const int nx = static_cast<int>(std::ceil(extent.x() / h)) + 1;
  const int ny = static_cast<int>(std::ceil(extent.y() / h)) + 1;
  const int nz = static_cast<int>(std::ceil(extent.z() / h)) + 1;
  VB_DEMAND(nx >= 2 && ny >= 2 && nz >= 2);
  auto node = [&](int i, int j, int k) { return (static_cast<std::int64_t>(k) * ny + j) * nx + i; };
  auto position = [&](std::int64_t id) {
    const int i = static_cast<int>(id % nx);
    const int j = static_cast<int>((id / nx) % ny);
    const int k = static_cast<int>(id / (static_cast<std::int64_t>(nx) * ny));
    return Eigen::Vector3d(box_min.x() + i * h, box_min.y() + j * h, box_min.z() + k * h);
  };
  std::vector<double> value(static_cast<std::size_t>(nx) * ny * nz);
  for (std::int64_t id = 0; id < static_cast<std::int64_t>(value.size()); ++id) {
    double v = f(position(id));
    if (std::abs(v) < 1e-4 * h) v = 1e-4 * h;
    value[static_cast<std::size_t>(id)] = v;
  }

  std::vector<Eigen::Vector3d> vertices;
  std::vector<int> faces;
  std::unordered_map<std::uint64_t, int> vertex_of_edge;
  const auto total_nodes = static_cast<std::uint64_t>(value.size());
  auto edge_vertex = [&](std::int64_t a, std::int64_t b) {
    if (a > b) std::swap(a, b);
    const std::uint64_t key =
        static_cast<std::uint64_t>(a) * total_nodes + static_cast<std::uint64_t>(b);
    const auto [it, inserted] = vertex_of_edge.try_emplace(key, static_cast<int>(vertices.size()));
    if (inserted) {
      const double fa = value[static_cast<std::size_t>(a)], fb = value[static_cast<std::size_t>(b)];
      const double t = fa / (fa - fb);
      vertices.push_back(position(a) + t * (position(b) - position(a)));
    }
    return it->second;
  };
  // Emits a triangle, oriented so its normal points from the inside corners to the outside.
  auto emit = [&](int v0, int v1, int v2, const Eigen::Vector3d& outward) {
    const Eigen::Vector3d n =
        (vertices[static_cast<std::size_t>(v1)] - vertices[static_cast<std::size_t>(v0)])
            .cross(vertices[static_cast<std::size_t>(v2)] - vertices[static_cast<std::size_t>(v0)]);
    if (n.dot(outward) < 0) std::swap(v1, v2);
    faces.insert(faces.end(), {v0, v1, v2});
  };

  std::array<std::int64_t, 8> corner;
  for (int k = 0; k + 1 < nz; ++k) {
    for (int j = 0; j + 1 < ny; ++j) {
      for (int i = 0; i + 1 < nx; ++i) {
        for (int c = 0; c < 8; ++c)
          corner[static_cast<std::size_t>(c)] =
              node(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
        for (const auto& tet : kTets) {
          std::array<std::int64_t, 4> inside{}, outside{};
          int n_in = 0, n_out = 0;
          for (int c : tet) {
            const std::int64_t id = corner[static_cast<std::size_t>(c)];
            if (value[static_cast<std::size_t>(id)] < 0) {
              inside[static_cast<std::size_t>(n_in++)] = id;
            } else {
              outside[static_cast<std::size_t>(n_out++)] = id;
            }
          }
          if (n_in == 0 || n_out == 0) continue;
          Eigen::Vector3d in_centre = Eigen::Vector3d::Zero(), out_centre = Eigen::Vector3d::Zero();
          for (int q = 0; q < n_in; ++q)
            in_centre += position(inside[static_cast<std::size_t>(q)]) / n_in;
          for (int q = 0; q < n_out; ++q)
            out_centre += position(outside[static_cast<std::size_t>(q)]) / n_out;
          const Eigen::Vector3d outward = out_centre - in_centre;
          if (n_in == 1 || n_out == 1) {
            const bool lone_inside = n_in == 1;
            const std::int64_t apex = lone_inside ? inside[0] : outside[0];
            const auto& others = lone_inside ? outside : inside;
            emit(edge_vertex(apex, others[0]), edge_vertex(apex, others[1]),
                 edge_vertex(apex, others[2]), outward);
          } else {
            // Two in, two out: the four crossed edges form a quad in this cyclic order.
            const int q0 = edge_vertex(inside[0], outside[0]);
            const int q1 = edge_vertex(inside[0], outside[1]);
            const int q2 = edge_vertex(inside[1], outside[1]);
            const int q3 = edge_vertex(inside[1], outside[0]);
            emit(q0, q1, q2, outward);
            emit(q0, q2, q3, outward);
          }
        }
      }
    }
  }
  geometry::TriangleMesh mesh;
  mesh.V.resize(3, static_cast<Eigen::Index>(vertices.size()));
  for (std::size_t v = 0; v < vertices.size(); ++v)
    mesh.V.col(static_cast<Eigen::Index>(v)) = vertices[v];
  mesh.F.resize(3, static_cast<Eigen::Index>(faces.size() / 3));
  for (std::size_t t = 0; t < faces.size() / 3; ++t) {
    for (int c = 0; c < 3; ++c)
      mesh.F(c, static_cast<Eigen::Index>(t)) = faces[3 * t + static_cast<std::size_t>(c)];
  }
  return mesh;
}

}  // namespace vb::perception
