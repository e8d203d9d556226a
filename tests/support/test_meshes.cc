#include "tests/support/test_meshes.h"

#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <utility>
#include <vector>

namespace vb::test {

geometry::TriangleMesh Box(double sx, double sy, double sz) {
  geometry::TriangleMesh m;
  m.V.resize(3, 8);
  for (int i = 0; i < 8; ++i)
    m.V.col(i) = Eigen::Vector3d((i & 1) * sx, ((i >> 1) & 1) * sy, ((i >> 2) & 1) * sz);
  m.F.resize(3, 12);
  m.F << 0, 0, 4, 4, 0, 0, 2, 2, 0, 0, 1, 1,  //
      2, 3, 5, 7, 1, 5, 6, 7, 4, 6, 3, 7,     //
      3, 1, 7, 6, 5, 4, 7, 3, 6, 2, 7, 5;
  return m;
}

geometry::TriangleMesh Tetrahedron() {
  geometry::TriangleMesh m;
  m.V.resize(3, 4);
  m.V << 1, -1, -1, 1,  //
      1, -1, 1, -1,     //
      1, 1, -1, -1;
  m.F.resize(3, 4);
  m.F << 0, 0, 0, 1,  //
      2, 1, 3, 2,     //
      1, 3, 2, 3;
  return m;
}

geometry::TriangleMesh Torus(double R, double r, int around, int across) {
  geometry::TriangleMesh m;
  m.V.resize(3, around * across);
  m.F.resize(3, 2 * around * across);
  auto id = [&](int i, int j) { return (i % around) * across + (j % across); };
  for (int i = 0; i < around; ++i) {
    const double u = 2.0 * std::numbers::pi * i / around;
    for (int j = 0; j < across; ++j) {
      const double v = 2.0 * std::numbers::pi * j / across;
      m.V.col(id(i, j)) << (R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u),
          r * std::sin(v);
    }
  }
  int f = 0;
  for (int i = 0; i < around; ++i) {
    for (int j = 0; j < across; ++j) {
      m.F.col(f++) << id(i, j), id(i + 1, j), id(i + 1, j + 1);
      m.F.col(f++) << id(i, j), id(i + 1, j + 1), id(i, j + 1);
    }
  }
  return m;
}

geometry::TriangleMesh Sphere(double r, int subdivisions) {
  std::vector<Eigen::Vector3d> v = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                    {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};
  std::vector<std::array<int, 3>> f = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                                       {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[static_cast<std::size_t>(a)] + v[static_cast<std::size_t>(b)]).normalized());
      return mid[key] = static_cast<int>(v.size()) - 1;
    };
    std::vector<std::array<int, 3>> next;
    for (const auto& t : f) {
      const int ab = midpoint(t[0], t[1]), bc = midpoint(t[1], t[2]), ca = midpoint(t[2], t[0]);
      next.push_back({t[0], ab, ca});
      next.push_back({ab, t[1], bc});
      next.push_back({ca, bc, t[2]});
      next.push_back({ab, bc, ca});
    }
    f = std::move(next);
  }
  geometry::TriangleMesh m;
  m.V.resize(3, static_cast<Eigen::Index>(v.size()));
  for (std::size_t i = 0; i < v.size(); ++i) m.V.col(static_cast<Eigen::Index>(i)) = r * v[i];
  m.F.resize(3, static_cast<Eigen::Index>(f.size()));
  for (std::size_t i = 0; i < f.size(); ++i) {
    for (int k = 0; k < 3; ++k)
      m.F(k, static_cast<Eigen::Index>(i)) = f[i][static_cast<std::size_t>(k)];
  }
  return m;
}

}  // namespace vb::test
