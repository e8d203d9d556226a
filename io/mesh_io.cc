#include "io/mesh_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <string>

#include "io/error.h"
#include "io/obj.h"
#include "io/off.h"
#include "io/pcd.h"
#include "io/xyz.h"

namespace vb::io {

FileFormat FormatFromPath(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".ply") return FileFormat::kPly;
  if (ext == ".off") return FileFormat::kOff;
  if (ext == ".obj") return FileFormat::kObj;
  if (ext == ".pcd") return FileFormat::kPcd;
  if (ext == ".xyz") return FileFormat::kXyz;
  throw InputError(path.string() + ": unknown file extension '" + ext +
                   "' (expected .ply, .off, .obj, .pcd or .xyz)");
}

std::string DropInvalidNormals(const std::string& source, Eigen::Matrix3Xd* normals) {
  if (normals->cols() == 0) return {};
  Eigen::Index invalid = 0;
  for (Eigen::Index i = 0; i < normals->cols(); ++i) {
    const double length = normals->col(i).norm();
    if (!std::isfinite(length) || length < 1e-6) {
      ++invalid;
    } else if (std::abs(length - 1.0) > 1e-9) {
      normals->col(i) /= length;
    }
  }
  if (invalid == 0) return {};
  const Eigen::Index total = normals->cols();
  normals->resize(3, 0);
  return source + ": " + std::to_string(invalid) + " of " + std::to_string(total) +
         " normals are zero-length or not finite; the file's normals are ignored (estimated from "
         "the points where needed)";
}

namespace {

void Report(const std::string& warning, std::vector<std::string>* warnings) {
  if (warning.empty()) return;
  if (warnings != nullptr) {
    warnings->push_back(warning);
  } else {
    std::fprintf(stderr, "warning: %s\n", warning.c_str());
  }
}

// The file at @p path in @p format as written: a mesh (perhaps without faces) for PLY, OFF and
// OBJ; the points and normals of a PCD or xyz cloud as vertices.
geometry::TriangleMesh ReadAny(const std::filesystem::path& path, FileFormat format,
                               const ReadLimits& limits) {
  geometry::TriangleMesh mesh;
  geometry::PointCloud cloud;
  switch (format) {
    case FileFormat::kPly:
      return ReadPly(path, limits);
    case FileFormat::kOff:
      return ReadOff(path, limits);
    case FileFormat::kObj:
      return ReadObj(path, limits);
    case FileFormat::kPcd:
      cloud = ReadPcd(path, limits);
      break;
    case FileFormat::kXyz:
      cloud = ReadXyz(path, limits);
      break;
  }
  mesh.V = std::move(cloud.points);
  mesh.N = std::move(cloud.normals);
  return mesh;
}

}  // namespace

geometry::TriangleMesh ReadMesh(const std::filesystem::path& path, const ReadLimits& limits,
                                std::vector<std::string>* warnings) {
  const FileFormat format = FormatFromPath(path);
  if (format == FileFormat::kPcd || format == FileFormat::kXyz)
    throw InputError(path.string() + ": holds a point cloud, but a triangle mesh is needed");
  geometry::TriangleMesh mesh = ReadAny(path, format, limits);
  if (mesh.num_faces() == 0)
    throw InputError(path.string() + ": has no faces, but a triangle mesh is needed");
  Report(DropInvalidNormals(path.string(), &mesh.N), warnings);
  return mesh;
}

geometry::TriangleMesh ReadMeshOrCloud(const std::filesystem::path& path, const ReadLimits& limits,
                                       std::vector<std::string>* warnings) {
  geometry::TriangleMesh mesh = ReadAny(path, FormatFromPath(path), limits);
  if (mesh.num_vertices() == 0) throw InputError(path.string() + ": holds no points");
  Report(DropInvalidNormals(path.string(), &mesh.N), warnings);
  return mesh;
}

geometry::PointCloud ReadCloud(const std::filesystem::path& path, const ReadLimits& limits,
                               std::vector<std::string>* warnings) {
  geometry::TriangleMesh mesh = ReadMeshOrCloud(path, limits, warnings);
  geometry::PointCloud cloud;
  cloud.points = std::move(mesh.V);
  cloud.normals = std::move(mesh.N);
  return cloud;
}

void WriteMesh(const std::filesystem::path& path, const geometry::TriangleMesh& mesh,
               const WriteOptions& options) {
  switch (FormatFromPath(path)) {
    case FileFormat::kPly:
      WritePly(path, mesh, options.ply_encoding);
      return;
    case FileFormat::kOff:
      WriteOff(path, mesh);
      return;
    case FileFormat::kObj:
      WriteObj(path, mesh);
      return;
    case FileFormat::kPcd:
    case FileFormat::kXyz:
      throw InputError(path.string() + ": cannot hold faces; write the mesh as .ply, .off or .obj");
  }
}

void WriteCloud(const std::filesystem::path& path, const geometry::PointCloud& cloud,
                const WriteOptions& options) {
  const FileFormat format = FormatFromPath(path);
  if (format == FileFormat::kPcd) return WritePcd(path, cloud);
  if (format == FileFormat::kXyz) return WriteXyz(path, cloud);
  geometry::TriangleMesh mesh;
  mesh.V = cloud.points;
  mesh.N = cloud.normals;
  mesh.F.resize(3, 0);
  if (format == FileFormat::kPly) return WritePly(path, mesh, options.ply_encoding);
  if (format == FileFormat::kOff) return WriteOff(path, mesh);
  WriteObj(path, mesh);
}

}  // namespace vb::io
