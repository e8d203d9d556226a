#include "io/obj.h"

#include <cstdio>
#include <fstream>
#include <vector>

#include "io/error.h"
#include "io/polygon_fan.h"
#include "io/text_scanner.h"

namespace vb::io {
namespace {

// Resolves a 1-based or negative (relative) OBJ index against the count seen so far.
int ResolveIndex(const internal::LineScanner& scan, std::int64_t index, std::size_t count,
                 const char* what) {
  const auto n = static_cast<std::int64_t>(count);
  const std::int64_t resolved = index < 0 ? n + index : index - 1;
  if (index == 0 || resolved < 0 || resolved >= n) {
    scan.Fail(std::string(what) + " index " + std::to_string(index) + " does not name one of the " +
              std::to_string(n) + " defined so far");
  }
  return static_cast<int>(resolved);
}

}  // namespace

geometry::TriangleMesh ReadObj(const std::filesystem::path& path, const ReadLimits& limits) {
  const std::string text = internal::ReadFileBounded(path, limits.max_file_bytes);
  internal::LineScanner scan(text, path.string());
  std::vector<double> positions;
  std::vector<double> normals;
  std::vector<int> triangles;
  std::vector<int> corner_normals;  // per triangle corner, -1 when absent
  std::vector<int> polygon;
  std::vector<int> polygon_normals;
  while (scan.NextLine()) {
    const std::string_view keyword = scan.tokens()[0];
    if (keyword == "v") {
      CheckLimit(path.string(), "vertices", static_cast<std::int64_t>(positions.size() / 3 + 1),
                 limits.max_points, "--max-points");
      for (std::size_t k = 1; k <= 3; ++k) positions.push_back(scan.Double(k, "vertex coordinate"));
    } else if (keyword == "vn") {
      CheckLimit(path.string(), "normals", static_cast<std::int64_t>(normals.size() / 3 + 1),
                 limits.max_points, "--max-points");
      for (std::size_t k = 1; k <= 3; ++k)
        normals.push_back(scan.DoubleOrNonFinite(k, "normal component"));
    } else if (keyword == "f") {
      const std::size_t n = scan.tokens().size() - 1;
      if (n < 3 || n > static_cast<std::size_t>(limits.max_polygon_vertices)) {
        scan.Fail("face has " + std::to_string(n) + " corners (allowed: 3 to " +
                  std::to_string(limits.max_polygon_vertices) + ")");
      }
      polygon.clear();
      polygon_normals.clear();
      for (std::size_t c = 1; c <= n; ++c) {
        const std::string_view corner = scan.tokens()[c];
        const std::size_t slash = corner.find('/');
        const int v = ResolveIndex(scan, scan.IntFrom(corner.substr(0, slash), "vertex index"),
                                   positions.size() / 3, "vertex");
        int vn = -1;
        if (slash != std::string_view::npos) {
          const std::size_t second = corner.find('/', slash + 1);
          if (second != std::string_view::npos && second + 1 < corner.size()) {
            vn = ResolveIndex(scan, scan.IntFrom(corner.substr(second + 1), "normal index"),
                              normals.size() / 3, "normal");
          }
        }
        for (int previous : polygon) {
          if (previous == v) scan.Fail("face repeats vertex " + std::to_string(v + 1));
        }
        polygon.push_back(v);
        polygon_normals.push_back(vn);
      }
      internal::AppendFan(polygon, &triangles);
      internal::AppendFan(polygon_normals, &corner_normals);
      CheckLimit(path.string(), "triangles", static_cast<std::int64_t>(triangles.size() / 3),
                 limits.max_faces, "--max-faces");
    }
  }
  geometry::TriangleMesh mesh;
  const auto nv = static_cast<Eigen::Index>(positions.size() / 3);
  mesh.V = Eigen::Map<const Eigen::Matrix3Xd>(positions.data(), 3, nv);
  mesh.F = internal::FacesFromFlat(triangles);
  // A cloud (no faces) pairs normals with vertices by index; a mesh keeps normals only when
  // they are a per-vertex attribute in disguise.
  if (triangles.empty() && normals.size() == positions.size()) {
    mesh.N = Eigen::Map<const Eigen::Matrix3Xd>(normals.data(), 3, nv);
  } else if (!normals.empty() && !corner_normals.empty()) {
    std::vector<int> normal_of_vertex(static_cast<std::size_t>(nv), -1);
    bool consistent = true;
    for (std::size_t c = 0; c < triangles.size() && consistent; ++c) {
      int& assigned = normal_of_vertex[static_cast<std::size_t>(triangles[c])];
      if (corner_normals[c] < 0 || (assigned >= 0 && assigned != corner_normals[c]))
        consistent = false;
      assigned = corner_normals[c];
    }
    for (int assigned : normal_of_vertex) consistent = consistent && assigned >= 0;
    if (consistent) {
      mesh.N.resize(3, nv);
      for (Eigen::Index i = 0; i < nv; ++i) {
        const auto n = static_cast<std::size_t>(normal_of_vertex[static_cast<std::size_t>(i)]);
        mesh.N.col(i) = Eigen::Vector3d(normals[3 * n], normals[3 * n + 1], normals[3 * n + 2]);
      }
    }
  }
  return mesh;
}

void WriteObj(const std::filesystem::path& path, const geometry::TriangleMesh& mesh) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path.string() + ": cannot open for writing");
  out << "# written by VirtualButcher\n";
  char buffer[128];
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    std::snprintf(buffer, sizeof(buffer), "v %.17g %.17g %.17g\n", mesh.V(0, i), mesh.V(1, i),
                  mesh.V(2, i));
    out << buffer;
  }
  for (int i = 0; i < (mesh.has_normals() ? mesh.num_vertices() : 0); ++i) {
    std::snprintf(buffer, sizeof(buffer), "vn %.17g %.17g %.17g\n", mesh.N(0, i), mesh.N(1, i),
                  mesh.N(2, i));
    out << buffer;
  }
  for (int f = 0; f < mesh.num_faces(); ++f) {
    out << 'f';
    for (int k = 0; k < 3; ++k) {
      const int index = mesh.F(k, f) + 1;
      out << ' ' << index;
      if (mesh.has_normals()) out << "//" << index;
    }
    out << '\n';
  }
  out.flush();
  if (!out) throw std::runtime_error(path.string() + ": write failed");
}

}  // namespace vb::io
