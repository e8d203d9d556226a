#include "io/off.h"

#include <cstdio>
#include <fstream>
#include <vector>

#include "io/error.h"
#include "io/polygon_fan.h"
#include "io/text_scanner.h"

namespace vb::io {

geometry::TriangleMesh ReadOff(const std::filesystem::path& path, const ReadLimits& limits) {
  const std::string text = internal::ReadFileBounded(path, limits.max_file_bytes);
  internal::LineScanner scan(text, path.string());
  if (!scan.NextLine()) scan.Fail("empty file, expected OFF header");
  const std::string_view magic = scan.tokens()[0];
  if (magic != "OFF" && magic != "NOFF" && magic != "COFF" && magic != "CNOFF") {
    scan.Fail("expected 'OFF', 'NOFF', 'COFF' or 'CNOFF', found '" + Excerpt(magic) + "'");
  }
  // Colours (COFF) follow the coordinates and normals; they are read past, not kept.
  const bool with_normals = magic == "NOFF" || magic == "CNOFF";
  std::size_t first = 1;  // counts may follow the keyword on the same line
  if (scan.tokens().size() == 1) {
    if (!scan.NextLine()) scan.Fail("missing vertex and face counts");
    first = 0;
  }
  const std::int64_t nv = scan.Int(first, "vertex count");
  const std::int64_t nf = scan.Int(first + 1, "face count");
  CheckLimit(path.string(), "vertices", nv, limits.max_points, "--max-points");
  CheckLimit(path.string(), "faces", nf, limits.max_faces, "--max-faces");
  // Each vertex needs at least "0 0 0\n", each face "3 0 1 2\n".
  if (nv < 0 || nf < 0 ||
      static_cast<std::uint64_t>(nv) * 6 + static_cast<std::uint64_t>(nf) * 8 > text.size()) {
    scan.Fail("counts " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
              " faces do not fit in a file of " + std::to_string(text.size()) + " bytes");
  }
  geometry::TriangleMesh mesh;
  mesh.V.resize(3, nv);
  if (with_normals) mesh.N.resize(3, nv);
  for (std::int64_t i = 0; i < nv; ++i) {
    if (!scan.NextLine())
      scan.Fail("file ends after " + std::to_string(i) + " of " + std::to_string(nv) + " vertices");
    for (int k = 0; k < 3; ++k)
      mesh.V(k, i) = scan.Double(static_cast<std::size_t>(k), "vertex coordinate");
    if (with_normals) {
      for (int k = 0; k < 3; ++k)
        mesh.N(k, i) = scan.DoubleOrNonFinite(static_cast<std::size_t>(3 + k), "vertex normal");
    }
  }
  std::vector<int> triangles;
  triangles.reserve(static_cast<std::size_t>(3 * nf));
  std::vector<int> polygon;
  for (std::int64_t f = 0; f < nf; ++f) {
    if (!scan.NextLine())
      scan.Fail("file ends after " + std::to_string(f) + " of " + std::to_string(nf) + " faces");
    const std::int64_t n = scan.Int(0, "polygon size");
    if (n < 3 || n > limits.max_polygon_vertices) {
      scan.Fail("polygon size " + std::to_string(n) + " is outside [3, " +
                std::to_string(limits.max_polygon_vertices) + "]");
    }
    polygon.clear();
    for (std::int64_t c = 0; c < n; ++c) {
      const std::int64_t index = scan.Int(static_cast<std::size_t>(1 + c), "vertex index");
      if (index < 0 || index >= nv) {
        scan.Fail("vertex index " + std::to_string(index) + " is outside [0, " +
                  std::to_string(nv) + ")");
      }
      for (int previous : polygon) {
        if (previous == index) scan.Fail("polygon repeats vertex " + std::to_string(index));
      }
      polygon.push_back(static_cast<int>(index));
    }
    internal::AppendFan(polygon, &triangles);
    CheckLimit(path.string(), "triangles", static_cast<std::int64_t>(triangles.size() / 3),
               limits.max_faces, "--max-faces");
  }
  mesh.F = internal::FacesFromFlat(triangles);
  return mesh;
}

void WriteOff(const std::filesystem::path& path, const geometry::TriangleMesh& mesh) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path.string() + ": cannot open for writing");
  out << (mesh.has_normals() ? "NOFF\n" : "OFF\n");
  out << mesh.num_vertices() << ' ' << mesh.num_faces() << " 0\n";
  char buffer[128];
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    std::snprintf(buffer, sizeof(buffer), "%.17g %.17g %.17g", mesh.V(0, i), mesh.V(1, i),
                  mesh.V(2, i));
    out << buffer;
    if (mesh.has_normals()) {
      std::snprintf(buffer, sizeof(buffer), " %.17g %.17g %.17g", mesh.N(0, i), mesh.N(1, i),
                    mesh.N(2, i));
      out << buffer;
    }
    out << '\n';
  }
  for (int f = 0; f < mesh.num_faces(); ++f) {
    out << "3 " << mesh.F(0, f) << ' ' << mesh.F(1, f) << ' ' << mesh.F(2, f) << '\n';
  }
  out.flush();
  if (!out) throw std::runtime_error(path.string() + ": write failed");
}

}  // namespace vb::io
